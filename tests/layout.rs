//! The house rules a newcomer relies on, checked on the source of both crates (the service's
//! `src/` and the engine's `crates/stereo-core/src/`): the route modules share downward and never
//! import each other, no module circle (in the Rust or in the page's JavaScript modules), each
//! crate's layers in the order its `lib.rs` states, every module with its `//!` line, no file
//! over 600 lines before its tests, and the engine's dependency tree free of HTTP, serde and
//! async.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

const SRC: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/src");
const CORE_SRC: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/crates/stereo-core/src");

/// The most lines a file in `src/` may have before its `#[cfg(test)]` part.
const MAX_LINES: usize = 600;

/// The engine's top-level modules in the order of its `lib.rs`'s map: each uses only those
/// before it.
const CORE_LAYERS: &[&str] = &[
    "numbers",
    "grid",
    "noise",
    "physics",
    "camera",
    "calibration",
    "vision",
    "pipeline",
];

/// The service's top-level modules in the order of its `lib.rs`'s map, all below the engine.
const LAYERS: &[&str] = &[
    "config", "budget", "observe", "api", "web", "server", "batch",
];

/// Each crate's source folder with its layers.
const CRATES: &[(&str, &[&str])] = &[(CORE_SRC, CORE_LAYERS), (SRC, LAYERS)];

/// Every `.rs` file under a crate's `src/` (but `main.rs`) with its module path
/// (`api::routes::rectify`).
fn modules(src: &str) -> BTreeMap<Vec<String>, PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in fs::read_dir(dir).expect("src/ readable") {
            let path = entry.expect("an entry").path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let mut files = Vec::new();
    walk(Path::new(src), &mut files);
    files
        .into_iter()
        .filter(|f| !f.ends_with("main.rs"))
        .map(|file| {
            let rel = file.strip_prefix(src).expect("under src/");
            let mut path: Vec<String> = rel
                .with_extension("")
                .iter()
                .map(|p| p.to_string_lossy().into_owned())
                .collect();
            if matches!(path.last().map(String::as_str), Some("mod" | "lib")) {
                path.pop();
            }
            (path, file)
        })
        .collect()
}

/// The code of a file without its comments, strings and `#[cfg(test)]` part.
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]") {
        Some(at) => &text[..at],
        None => text,
    };
    let bytes = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'/' if bytes.get(i + 1) == Some(&b'/') => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
            }
            b'/' if bytes.get(i + 1) == Some(&b'*') => {
                i += 2;
                while i + 1 < bytes.len() && !(bytes[i] == b'*' && bytes[i + 1] == b'/') {
                    i += 1;
                }
                i += 2;
            }
            b'"' => {
                i += 1;
                while i < bytes.len() && bytes[i] != b'"' {
                    i += if bytes[i] == b'\\' { 2 } else { 1 };
                }
                i += 1;
                out.push_str("\"\"");
            }
            b'\'' if bytes.get(i + 2) == Some(&b'\'') || bytes.get(i + 1) == Some(&b'\\') => {
                // A char literal ('a', '\n', '\''); a lifetime has no closing quote.
                i += 1;
                while i < bytes.len() && bytes[i] != b'\'' {
                    i += if bytes[i] == b'\\' { 2 } else { 1 };
                }
                i += 1;
            }
            b => {
                out.push(b as char);
                i += 1;
            }
        }
    }
    out
}

/// The paths a file's code names: each `use` tree expanded, and every `crate::…`, `super::…`
/// and `self::…` path written inline.
fn paths_in(code: &str) -> Vec<Vec<String>> {
    paths_in_with(code, true, &[])
}

/// A crate's `macro_rules!` macros: each name with the path (`crate::…`) of the module that
/// defines it.
type Macros = Vec<(String, Vec<String>)>;

/// The `macro_rules!` macros each module of `modules` defines.
fn macros_of(modules: &BTreeMap<Vec<String>, PathBuf>) -> Macros {
    let mut found = Vec::new();
    for (module, file) in modules {
        let code = code_of(&fs::read_to_string(file).expect("readable"));
        for part in code.split("macro_rules!").skip(1) {
            let name: String = part
                .trim_start()
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            let mut path = vec!["crate".to_owned()];
            path.extend(module.iter().cloned());
            found.push((name, path));
        }
    }
    found
}

/// Whether `code` invokes the macro `name` (`name!`, not its `macro_rules!` definition).
fn uses_macro(code: &str, name: &str) -> bool {
    let call = format!("{name}!");
    let mut from = 0;
    while let Some(at) = code[from..].find(&call) {
        let i = from + at;
        from = i + call.len();
        let before = code[..i].trim_end();
        let word_edge = !code[..i]
            .chars()
            .last()
            .is_some_and(|c| c.is_alphanumeric() || c == '_');
        if word_edge && !before.ends_with("macro_rules!") {
            return true;
        }
    }
    false
}

/// [`paths_in`], leaving out `pub use` re-exports unless `re_exports`: a module's facade
/// names its children's items without using them.
fn paths_in_with(
    code: &str,
    re_exports: bool,
    macros: &[(String, Vec<String>)],
) -> Vec<Vec<String>> {
    let mut paths = Vec::new();
    let words = |s: &str| -> Vec<String> {
        s.split("::")
            .map(|w| w.trim().to_owned())
            .filter(|w| !w.is_empty())
            .collect()
    };
    // `use` trees.
    let mut rest = code;
    while let Some(at) = find_word(rest, "use") {
        let after = &rest[at + 3..];
        let end = after.find(';').unwrap_or(after.len());
        let exported =
            rest[..at].trim_end().ends_with("pub") || rest[..at].trim_end().ends_with("pub(crate)");
        if re_exports || !exported {
            expand(&mut paths, Vec::new(), &after[..end]);
        }
        rest = &after[end..];
    }
    // Bare inline paths (`stream::Streams`, `census::transform(…)`, a macro's
    // `chart::router()`): [`resolve`] keeps those whose first word is a child module.
    let uses: Vec<(usize, usize)> = {
        let mut spans = Vec::new();
        let mut from = 0;
        while let Some(at) = find_word(&code[from..], "use") {
            let begin = from + at;
            let end = code[begin..].find(';').map_or(code.len(), |e| begin + e);
            spans.push((begin, end));
            from = end;
        }
        spans
    };
    let mut from = 0;
    while let Some(at) = code[from..].find("::") {
        let colons = from + at;
        from = colons + 2;
        if uses.iter().any(|&(b, e)| (b..e).contains(&colons)) {
            continue;
        }
        let start = code[..colons]
            .rfind(|c: char| !(c.is_alphanumeric() || c == '_'))
            .map_or(0, |i| i + 1);
        let word = &code[start..colons];
        let before = code[..start].chars().last();
        if word.is_empty()
            || before.is_some_and(|c| c == ':' || c == '$')
            || ["crate", "super", "self"].contains(&word)
        {
            continue;
        }
        let end = code[start..]
            .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
            .map_or(code.len(), |e| start + e);
        paths.push(words(&code[start..end]));
    }
    // Macros by their `macro_rules!` name: a use of the module that defines them.
    for (name, module) in macros {
        if uses_macro(code, name) {
            paths.push(module.clone());
        }
    }
    // Inline paths (those in `use` trees were read above).
    for start in ["crate::", "super::", "self::"] {
        let mut from = 0;
        while let Some(at) = code[from..].find(start) {
            let begin = from + at;
            from = begin + start.len();
            if uses.iter().any(|&(b, e)| (b..e).contains(&begin)) {
                continue;
            }
            if code[..begin]
                .chars()
                .last()
                .is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':')
            {
                continue;
            }
            let end = code[begin..]
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .map_or(code.len(), |e| begin + e);
            paths.push(words(&code[begin..end]));
        }
    }
    paths
}

/// The index of `word` in `s` as a whole word.
fn find_word(s: &str, word: &str) -> Option<usize> {
    let mut from = 0;
    while let Some(at) = s[from..].find(word) {
        let i = from + at;
        let before = s[..i].chars().last();
        let after = s[i + word.len()..].chars().next();
        let edge = |c: Option<char>| !c.is_some_and(|c| c.is_alphanumeric() || c == '_');
        if edge(before) && after.is_some_and(char::is_whitespace) {
            return Some(i);
        }
        from = i + word.len();
    }
    None
}

/// Expands one `use` tree (`a::{b, c::{d, e}}`) onto `prefix`.
fn expand(out: &mut Vec<Vec<String>>, prefix: Vec<String>, tree: &str) {
    let tree = tree.trim();
    let tree = tree.split(" as ").next().unwrap_or(tree).trim();
    if let Some(open) = tree.find('{') {
        let mut head = prefix;
        head.extend(
            tree[..open]
                .split("::")
                .map(str::trim)
                .filter(|w| !w.is_empty())
                .map(str::to_owned),
        );
        let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
        let mut depth = 0;
        let mut start = 0;
        for (i, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    expand(out, head.clone(), &inner[start..i]);
                    start = i + 1;
                }
                _ => {}
            }
        }
        expand(out, head, &inner[start..]);
    } else if !tree.is_empty() {
        let mut path = prefix;
        path.extend(tree.split("::").map(|w| w.trim().to_owned()));
        out.push(path);
    }
}

/// The module a path names (the longest known module it starts with), from the module `at`.
fn resolve(path: &[String], at: &[String], known: &BTreeSet<Vec<String>>) -> Option<Vec<String>> {
    let mut base: Vec<String> = at.to_vec();
    let mut rest = path;
    match rest.first().map(String::as_str) {
        Some("crate") => {
            base.clear();
            rest = &rest[1..];
        }
        Some("self") => rest = &rest[1..],
        Some("super") => {
            while rest.first().is_some_and(|w| w == "super") {
                base.pop();
                rest = &rest[1..];
            }
        }
        Some(first) => {
            // A child module named bare (`use types::X;`, `stream::Streams`).
            let mut child = at.to_vec();
            child.push(first.to_owned());
            if !known.contains(&child) {
                return None;
            }
        }
        None => return None,
    }
    let mut full = base;
    let mut found = None;
    if known.contains(&full) {
        found = Some(full.clone());
    }
    for word in rest {
        full.push(word.clone());
        if known.contains(&full) {
            found = Some(full.clone());
        }
    }
    found
}

/// Module → the modules of its own crate its code names.
fn graph(src: &str) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    graph_with(src, true)
}

/// [`graph`], with `pub use` re-exports counted as uses or not.
fn graph_with(src: &str, re_exports: bool) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    let modules = modules(src);
    let known: BTreeSet<Vec<String>> = modules.keys().cloned().collect();
    let macros = macros_of(&modules);
    modules
        .iter()
        .map(|(module, file)| {
            let code = code_of(&fs::read_to_string(file).expect("readable"));
            let uses = paths_in_with(&code, re_exports, &macros)
                .iter()
                .filter_map(|p| resolve(p, module, &known))
                .filter(|m| m != module)
                .collect();
            (module.clone(), uses)
        })
        .collect()
}

/// The circles among the siblings under each module: each child stands for its whole
/// subtree, an edge from a child's subtree to another's is an edge between the two, and a
/// strongly connected set of more than one child is a circle.
fn circles<N: Ord + Clone + std::fmt::Debug>(edges: &BTreeMap<N, BTreeSet<N>>) -> Vec<BTreeSet<N>> {
    // Tarjan's algorithm would do; the graphs are small, so reachability both ways.
    let reach = |from: &N| -> BTreeSet<N> {
        let mut seen = BTreeSet::new();
        let mut stack = vec![from.clone()];
        while let Some(n) = stack.pop() {
            for m in edges.get(&n).into_iter().flatten() {
                if seen.insert(m.clone()) {
                    stack.push(m.clone());
                }
            }
        }
        seen
    };
    let nodes: BTreeSet<N> = edges.keys().cloned().collect();
    let reaches: BTreeMap<N, BTreeSet<N>> = nodes.iter().map(|n| (n.clone(), reach(n))).collect();
    let mut found: Vec<BTreeSet<N>> = Vec::new();
    for n in &nodes {
        let set: BTreeSet<N> = nodes
            .iter()
            .filter(|m| *m == n || (reaches[n].contains(*m) && reaches[*m].contains(n)))
            .cloned()
            .collect();
        if set.len() > 1 && !found.contains(&set) {
            found.push(set);
        }
    }
    found
}

/// The sibling graph under `parent`: the child each module lies in → the children it uses.
fn siblings(
    graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
    parent: &[String],
) -> BTreeMap<String, BTreeSet<String>> {
    let child_of = |m: &[String]| -> Option<String> {
        (m.len() > parent.len() && m.starts_with(parent)).then(|| m[parent.len()].clone())
    };
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (from, uses) in graph {
        let Some(a) = child_of(from) else { continue };
        let entry = edges.entry(a.clone()).or_default();
        for to in uses {
            if let Some(b) = child_of(to).filter(|b| *b != a) {
                entry.insert(b);
            }
        }
    }
    edges
}

/// The children of `parent` that `parent`'s own file uses and whose subtree uses `parent`'s
/// own items back.
fn parent_and_child_circles(
    graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
    parent: &[String],
) -> Vec<String> {
    let child_of = |m: &[String]| -> Option<String> {
        (m.len() > parent.len() && m.starts_with(parent)).then(|| m[parent.len()].clone())
    };
    let used: BTreeSet<String> = graph
        .get(parent)
        .into_iter()
        .flatten()
        .filter_map(|m| child_of(m))
        .collect();
    used.into_iter()
        .filter(|child| {
            graph.iter().any(|(from, uses)| {
                child_of(from).as_ref() == Some(child) && uses.iter().any(|u| u == parent)
            })
        })
        .collect()
}

fn show(m: &[String]) -> String {
    if m.is_empty() {
        "crate".to_owned()
    } else {
        m.join("::")
    }
}

/// No module under `api::routes::X` names anything under `api::routes::Y`: what two routes
/// share lives below them.
#[test]
fn no_route_imports_another() {
    let graph = graph(SRC);
    let routes: Vec<String> = ["api", "routes"].map(str::to_owned).to_vec();
    let sideways: Vec<String> = siblings(&graph, &routes)
        .iter()
        .flat_map(|(a, uses)| uses.iter().map(move |b| format!("{a} → {b}")))
        .collect();
    assert!(
        sideways.is_empty(),
        "route modules import each other: {sideways:?}"
    );
}

/// The callers of the engine's depth job: the `/depth-map` and `/match` routes, a stream's
/// frames, and the `depth-map` command's frames and its check before them.
const DEPTH_CALLERS: &[&[&str]] = &[
    &["api", "routes", "depth_map"],
    &["api", "routes", "matching"],
    &["api", "images", "stream"],
    &["batch", "engine"],
    &["batch", "preflight"],
];

/// One depth job for every caller: each plans its work through the engine's `DepthJob`
/// (`api::images::job::plan`), none imports another caller or any route, and none decides
/// the end of the search itself: the calibration file's range is the engine's default, set
/// where the job is planned and read in `Params::new` alone.
#[test]
fn every_depth_caller_plans_one_job() {
    let graph = graph(SRC);
    let owned = |m: &[&str]| m.iter().map(|w| (*w).to_owned()).collect::<Vec<String>>();
    let callers: Vec<Vec<String>> = DEPTH_CALLERS.iter().map(|m| owned(m)).collect();
    let job = owned(&["api", "images", "job"]);
    let routes = owned(&["api", "routes"]);
    let mut wrong = Vec::new();
    for caller in &callers {
        let uses = graph.get(caller).expect("a caller's module");
        if !uses.contains(&job) {
            wrong.push(format!(
                "{} does not plan through api::images::job",
                show(caller)
            ));
        }
        for used in uses {
            let is_caller = callers.iter().any(|c| c != caller && used.starts_with(c));
            let is_route = !caller.starts_with(&routes) && used.starts_with(&routes);
            if is_caller || is_route {
                wrong.push(format!("{} → {}", show(caller), show(used)));
            }
        }
    }
    for (module, file) in modules(SRC) {
        let code = code_of(&fs::read_to_string(&file).expect("readable"));
        if code.contains("file_range") || code.contains("Params::new") {
            wrong.push(format!("{} decides the matcher's defaults", show(&module)));
        }
    }
    let core = code_of(&fs::read_to_string(format!("{CORE_SRC}/pipeline/job.rs")).expect("job.rs"));
    assert!(core.contains("settings.file_range =") && core.contains("Params::new(&settings)"));
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// Each rig input parsed once at its edge: a form (`api::images::form`), a stream's settings
/// (`api::images::stream`, once for the stream), the command's flags (`batch::preflight`,
/// which hands the parsed input to the command's engine), `/calibration/check`'s calibration
/// and `/calibrate`'s earlier one (`initial`) each turn the
/// rig's parts into the engine's `RigInput` once, and only `api::images::rig` builds one; no
/// depth caller reads a calibration file itself, each making the rig of a frame size from its
/// `RigInput` (`job::plan_at`).
#[test]
fn each_rig_input_is_parsed_once_at_its_edge() {
    let edges: BTreeMap<String, usize> = [
        ("api::images::form", 1),
        ("api::images::stream", 1),
        ("api::routes::board_calibration::initial", 1),
        ("api::routes::calibration_check", 1),
        ("batch::preflight", 1),
    ]
    .into_iter()
    .map(|(m, n)| (m.to_owned(), n))
    .collect();
    let mut parsing = BTreeMap::new();
    let mut wrong = Vec::new();
    for (module, file) in modules(SRC) {
        let code = code_of(&fs::read_to_string(&file).expect("readable"));
        let name = show(&module);
        let parses = code.matches("rig::parsed(").count() + code.matches("rig::input(").count();
        if parses > 0 {
            parsing.insert(name.clone(), parses);
        }
        let builds = code.contains("RigInput::file(") || code.contains("RigInput::members(");
        if builds && name != "api::images::rig" {
            wrong.push(format!("{name} builds a RigInput"));
        }
        let caller = DEPTH_CALLERS.iter().any(|c| module == c.to_vec());
        if caller && (code.contains("files::read(") || code.contains("Calibrated::from_file(")) {
            wrong.push(format!("{name} reads a calibration file itself"));
        }
    }
    assert_eq!(
        parsing, edges,
        "the modules that parse a rig input, and how often"
    );
    let engine = code_of(&fs::read_to_string(format!("{SRC}/batch/engine.rs")).expect("engine"));
    assert!(engine.contains("job::plan_at(") && engine.contains("calibration: RigInput"));
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// The maths out of the routes: the rig design's figures are the engine's
/// (`physics::design`), which `/rig` and `/baseline` only word; no route computes a depth
/// error, a disparity at a distance or a baseline itself, nor remaps a frame but for the file
/// it answers.
#[test]
fn the_routes_leave_the_maths_to_the_engine() {
    let maths = [
        "baseline_for(",
        "distance_at_relative_error(",
        ".relative_error_at(",
        ".depth_error_at(",
        ".disparity_at(",
        "remap_grey(",
    ];
    let mut wrong = Vec::new();
    for (module, file) in modules(SRC) {
        if !module.starts_with(&["api".to_owned(), "routes".to_owned()]) {
            continue;
        }
        let code = code_of(&fs::read_to_string(&file).expect("readable"));
        for call in maths.iter().filter(|m| code.contains(*m)) {
            wrong.push(format!("{} calls {call}", show(&module)));
        }
    }
    let design = fs::read_to_string(format!("{SRC}/api/routes/rig_design/mod.rs")).expect("rig");
    assert!(design.contains("design::baseline_design(") && design.contains(".budget_reach("));
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// The most lines `src/api/routes/` may hold: the routes only translate (wire types to the
/// engine's, one call, its faults to problem+json); the wire types live in `api::wire`.
const MAX_ROUTE_LINES: usize = 4_500;
/// The most lines a function of a route module (a handler or the work it runs) may have.
const MAX_HANDLER_LINES: usize = 60;
/// The most paths of the engine `/calibrate`'s modules may import.
const MAX_CALIBRATE_CORE_PATHS: usize = 5;
/// What no route may import: the engine's geometry and the matcher's insides, which its
/// `pipeline` wraps, and linear algebra.
const GEOMETRY: &[&str] = &[
    "stereo_core::camera",
    "stereo_core::calibration::boards",
    "stereo_core::vision::remap",
    "stereo_core::vision::correspond",
    "stereo_core::vision::census",
    "stereo_core::vision::cost",
    "stereo_core::vision::sgm",
    "stereo_core::vision::refine",
    "stereo_core::vision::rows",
    "stereo_core::vision::pyramid",
    "stereo_core::vision::filters",
    "stereo_core::vision::sigma",
    "stereo_core::vision::plane",
    "stereo_core::vision::encode",
    "nalgebra",
];

/// Every route module's file with its code (comments and strings out).
fn route_files() -> Vec<(PathBuf, String)> {
    modules(SRC)
        .into_iter()
        .filter(|(m, _)| m.starts_with(&["api".to_owned(), "routes".to_owned()]))
        .map(|(_, file)| {
            let code = code_of(&fs::read_to_string(&file).expect("readable"));
            (file, code)
        })
        .collect()
}

/// The functions of `code` (handlers and the synchronous work they call alike) with their
/// line counts.
fn handlers(code: &str) -> Vec<(String, usize)> {
    let mut found = Vec::new();
    let lines: Vec<&str> = code.lines().collect();
    for (i, line) in lines.iter().enumerate() {
        let Some(at) = find_word(line, "fn") else {
            continue;
        };
        let name: String = line[at + 3..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let tail = line.trim_end();
        if name.is_empty() || tail.ends_with(';') {
            continue;
        }
        if tail.ends_with('}') {
            found.push((name, 1));
            continue;
        }
        let indent = line.len() - line.trim_start().len();
        let end = lines[i + 1..]
            .iter()
            .position(|l| {
                l.len() - l.trim_start().len() == indent && l.trim_start().starts_with('}')
            })
            .map_or(lines.len(), |e| i + 1 + e);
        found.push((name, end - i + 1));
    }
    found
}

/// The routes only translate: `src/api/routes/` within its line budget, no handler over
/// 60 lines, no route importing the engine's geometry or the matcher's insides, and
/// `/calibrate` importing at most 5 of the engine's paths.
#[test]
fn the_routes_only_translate() {
    let files = route_files();
    assert!(files.len() >= 15, "{files:?}");
    let mut wrong = Vec::new();
    let total: usize = files
        .iter()
        .map(|(file, _)| fs::read_to_string(file).expect("readable").lines().count())
        .sum();
    if total >= MAX_ROUTE_LINES {
        wrong.push(format!(
            "src/api/routes/ has {total} lines, {MAX_ROUTE_LINES} at most"
        ));
    }
    let mut handler_count = 0;
    let mut calibrate_paths = BTreeSet::new();
    for (file, code) in &files {
        for (name, lines) in handlers(code) {
            handler_count += 1;
            if lines > MAX_HANDLER_LINES {
                wrong.push(format!("{} has {lines} lines", name));
            }
        }
        for path in paths_in(code) {
            let joined = path.join("::");
            if let Some(g) = GEOMETRY.iter().find(|g| joined.starts_with(*g)) {
                wrong.push(format!("{} imports {joined} ({g})", file.display()));
            }
            if joined.starts_with("stereo_core")
                && file.to_string_lossy().contains("board_calibration")
            {
                calibrate_paths.insert(joined);
            }
        }
    }
    assert!(handler_count >= 8, "handlers found: {handler_count}");
    if calibrate_paths.is_empty() || calibrate_paths.len() > MAX_CALIBRATE_CORE_PATHS {
        wrong.push(format!(
            "/calibrate imports {calibrate_paths:?} from the engine"
        ));
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// The route checks see what they look for: a handler's length, and an import's path.
#[test]
fn the_route_checks_see_what_they_look_for() {
    let code = "pub async fn a(\n    x: u8,\n) -> u8 {\n    x\n}\n\nfn b() {}\nfn c() {\n}\n";
    let found = vec![
        ("a".to_owned(), 5),
        ("b".to_owned(), 1),
        ("c".to_owned(), 2),
    ];
    assert_eq!(handlers(code), found);
    let paths = paths_in("use stereo_core::camera::{Alpha, stereo_rectify};");
    assert!(
        paths
            .iter()
            .any(|p| p.join("::") == "stereo_core::camera::Alpha")
    );
}

/// No circle among the modules of any level: at every module, its children (each standing
/// for its subtree) use one another one way only; and no module and its child use each other
/// (the parent's own code using the child, not merely re-exporting it, and the child's subtree
/// using the parent's own items).
#[test]
fn no_module_circle() {
    let mut found = Vec::new();
    for (src, _) in CRATES {
        let graph = graph(src);
        let imports = graph_with(src, false);
        for parent in graph.keys() {
            for circle in circles(&siblings(&graph, parent)) {
                found.push(format!("under {}: {circle:?}", show(parent)));
            }
            for child in parent_and_child_circles(&imports, parent) {
                found.push(format!("{} and its child {child}", show(parent)));
            }
        }
    }
    assert!(found.is_empty(), "import circles: {found:#?}");
}

/// Each crate's top-level modules use only those before them in its `lib.rs`'s map.
#[test]
fn layers_use_only_those_above() {
    let mut wrong = Vec::new();
    for (src, layers) in CRATES {
        let graph = graph(src);
        let top = siblings(&graph, &[]);
        assert!(top.len() >= layers.len() - 1, "{src}: {top:?}");
        for (a, uses) in &top {
            let Some(i) = layers.iter().position(|l| l == a) else {
                wrong.push(format!("{a} is not in the layer list"));
                continue;
            };
            for b in uses {
                let j = layers.iter().position(|l| l == b);
                if j.is_none_or(|j| j >= i) {
                    wrong.push(format!("{a} uses {b}, which is not above it"));
                }
            }
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// `cargo tree -p stereo-core` over normal edges, one package name a line, to `depth`.
fn engine_tree(depth: &str) -> BTreeSet<String> {
    let out = std::process::Command::new(env!("CARGO"))
        .args([
            "tree",
            "--offline",
            "--locked",
            "-p",
            "stereo-core",
            "-e",
            "normal",
        ])
        .args(["--prefix", "none", "--format", "{p}", "--depth", depth])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo tree runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|line| line.split_whitespace().next())
        .map(str::to_owned)
        .collect()
}

/// The engine depends on no HTTP, async or OpenAPI crate anywhere in its tree, and on no serde
/// crate itself, so that its purity is the compiler's, not this file's: code cannot name a crate
/// its manifest does not list. (serde is in the tree below the chessboard detector,
/// `calib-targets-chessboard`, whose own dataset types derive it and which turns on nalgebra's
/// serde feature; no engine signature can mention it.)
#[test]
fn the_engine_depends_on_no_http_serde_or_async() {
    let whole = engine_tree("100");
    assert!(
        whole.contains("stereo-core") && whole.contains("nalgebra") && whole.len() > 20,
        "{whole:?}"
    );
    let never = [
        "axum",
        "tokio",
        "hyper",
        "http",
        "http-body",
        "tower",
        "tower-http",
        "utoipa",
        "futures-util",
        "mio",
        "clap",
    ];
    let found: Vec<&str> = never.into_iter().filter(|f| whole.contains(*f)).collect();
    assert!(found.is_empty(), "the engine's tree holds {found:?}");
    let direct = engine_tree("1");
    let own: Vec<&String> = direct
        .iter()
        .filter(|d| d.starts_with("serde") || never.contains(&d.as_str()))
        .collect();
    assert!(own.is_empty(), "the engine depends on {own:?}");
}

/// Every module opens with a `//!` line saying what it is for, and none has over 600 lines
/// before its tests.
#[test]
fn every_module_says_what_it_is_for_and_is_short() {
    let mut wrong = Vec::new();
    for (src, module, file) in CRATES
        .iter()
        .flat_map(|(src, _)| modules(src).into_iter().map(move |(m, f)| (*src, m, f)))
    {
        let text = fs::read_to_string(&file).expect("readable");
        if !text.trim_start().starts_with("//!") {
            wrong.push(format!("{} has no //! line", show(&module)));
        }
        let lines = match text.find("#[cfg(test)]") {
            Some(at) => text[..at].lines().count(),
            None => text.lines().count(),
        };
        let rel = file
            .strip_prefix(src)
            .expect("under src/")
            .to_string_lossy();
        if lines > MAX_LINES {
            wrong.push(format!(
                "{rel} has {lines} lines before its tests, over {MAX_LINES}"
            ));
        }
    }
    main_too(&mut wrong);
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// Every file in `src/` is a module its parent declares (`mod name;`), so that none (a test
/// file above all) is silently left out of the build.
#[test]
fn every_file_is_declared_by_its_parent() {
    let mut wrong = Vec::new();
    for (src, _) in CRATES {
        let modules = modules(src);
        for (module, file) in &modules {
            let Some((name, parent)) = module.split_last() else {
                continue;
            };
            let Some(parent_file) = modules.get(parent) else {
                wrong.push(format!("{} has no parent module", file.display()));
                continue;
            };
            let text = fs::read_to_string(parent_file).expect("readable");
            let declared = text.lines().any(|line| {
                let line = line.trim_start();
                let line = line.strip_prefix("pub ").unwrap_or(line);
                let line = line.strip_prefix("pub(crate) ").unwrap_or(line);
                line == format!("mod {name};")
            });
            if !declared {
                wrong.push(format!(
                    "{} is not declared in {}",
                    file.display(),
                    parent_file.display()
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}

fn main_too(wrong: &mut Vec<String>) {
    let main = fs::read_to_string(Path::new(SRC).join("main.rs")).expect("main.rs");
    if !main.trim_start().starts_with("//!") {
        wrong.push("main.rs has no //! line".to_owned());
    }
}

/// The page's JavaScript modules import one another one way only.
#[test]
fn no_circle_in_the_page_modules() {
    let dir = Path::new(SRC).join("web/js");
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for entry in fs::read_dir(&dir).expect("src/web/js") {
        let path = entry.expect("an entry").path();
        if path.extension().is_none_or(|e| e != "js") {
            continue;
        }
        let name = path
            .file_name()
            .expect("a name")
            .to_string_lossy()
            .into_owned();
        let text = fs::read_to_string(&path).expect("readable");
        let uses = edges.entry(name).or_default();
        for line in text.lines() {
            let Some(from) = line.find("from './") else {
                continue;
            };
            let rest = &line[from + 8..];
            if let Some(end) = rest.find('\'') {
                uses.insert(rest[..end].to_owned());
            }
        }
    }
    assert!(edges.len() >= 5, "the page's modules found: {edges:?}");
    let found = circles(&edges);
    assert!(found.is_empty(), "import circles in src/web/js: {found:?}");
}

/// The checker itself finds a circle and a route importing another, so that its silence means
/// something.
#[test]
fn the_checker_sees_what_it_looks_for() {
    let code = code_of(
        "//! x\nuse crate::api::{routes::rectify::plan, wire::{rig::Rig, de}};\n\
         // use crate::budget;\nfn f() { let s = \"crate::vision\"; super::images::work::run(); }",
    );
    let paths = paths_in(&code);
    assert!(
        paths.contains(
            &["crate", "api", "routes", "rectify", "plan"]
                .map(String::from)
                .to_vec()
        )
    );
    assert!(paths.contains(&["crate", "api", "wire", "de"].map(String::from).to_vec()));
    assert!(
        paths.contains(
            &["super", "images", "work", "run"]
                .map(String::from)
                .to_vec()
        )
    );
    assert!(
        !paths
            .iter()
            .any(|p| p.contains(&"budget".to_owned()) || p.contains(&"vision".to_owned()))
    );
    let edges: BTreeMap<&str, BTreeSet<&str>> = [
        ("a", BTreeSet::from(["b"])),
        ("b", BTreeSet::from(["c"])),
        ("c", BTreeSet::from(["a"])),
        ("d", BTreeSet::from(["a"])),
    ]
    .into_iter()
    .collect();
    assert_eq!(circles(&edges), vec![BTreeSet::from(["a", "b", "c"])]);
}

/// The README is for users: at most 900 lines, and no internal issue numbers (histories and
/// per-issue tables live in `docs/`).
#[test]
fn the_readme_is_for_users() {
    let readme =
        fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).expect("README.md");
    let lines = readme.lines().count();
    assert!(lines <= 900, "README.md has {lines} lines, 900 at most");
    let numbered: Vec<&str> = readme
        .lines()
        .filter(|l| {
            let l = l.to_lowercase();
            (0..10).any(|d| l.contains(&format!("issue {d}")))
        })
        .collect();
    assert!(
        numbered.is_empty(),
        "issue numbers in README.md: {numbered:#?}"
    );
}
