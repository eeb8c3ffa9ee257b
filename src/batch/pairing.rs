//! Which files of a recording make a pair: by the camera named in each file's name (left and
//! right, l and r, cam0 and cam1, im0 and im1), as the page pairs the files dropped on it, or by
//! the same name in two folders.

use std::cmp::Ordering;
use std::path::{Path, PathBuf};

/// The camera a file name names, and the name with that part replaced by `*` (lower case,
/// without its extension): two files with the same key are a pair.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Side {
    pub left: bool,
    pub key: String,
}

/// A left and a right frame, and the name their outputs take (the left frame's, without its
/// extension).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FramePair {
    pub name: String,
    pub left: PathBuf,
    pub right: PathBuf,
}

/// A file left out, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Unpaired {
    pub path: PathBuf,
    pub reason: String,
}

/// Whether the file is a PNG or JPEG by its extension.
pub fn is_image(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
}

/// The camera `file_name` names, as the page's `sideOf` reads it: `left` or `right`; else an
/// `l` or `r` standing alone between non-letters; else `im`, `cam`, `image` or `image_`
/// followed by 0 (left) or 1 (right) and no further digit.
pub fn side_of(file_name: &str) -> Option<Side> {
    let lower = file_name.to_lowercase();
    let name = match lower.rfind('.') {
        Some(dot) if is_image(Path::new(&lower)) => &lower[..dot],
        _ => lower.as_str(),
    };
    let bytes = name.as_bytes();
    let letter = |i: Option<usize>| {
        i.and_then(|i| bytes.get(i))
            .is_some_and(u8::is_ascii_lowercase)
    };
    let key = |at: usize, len: usize| format!("{}*{}", &name[..at], &name[at + len..]);
    let words = [("left", true), ("right", false)];
    if let Some((at, word, left)) = words
        .iter()
        .filter_map(|&(w, left)| name.find(w).map(|at| (at, w, left)))
        .min()
    {
        return Some(Side {
            left,
            key: key(at, word.len()),
        });
    }
    for (at, &b) in bytes.iter().enumerate() {
        if (b == b'l' || b == b'r') && !letter(at.checked_sub(1)) && !letter(Some(at + 1)) {
            return Some(Side {
                left: b == b'l',
                key: key(at, 1),
            });
        }
    }
    for at in 0..bytes.len() {
        if letter(at.checked_sub(1)) {
            continue;
        }
        for prefix in ["image_", "image", "cam", "im"] {
            let rest = &name[at..];
            if let Some(tail) = rest.strip_prefix(prefix)
                && let Some(&digit) = tail.as_bytes().first()
                && (digit == b'0' || digit == b'1')
                && !tail.as_bytes().get(1).is_some_and(u8::is_ascii_digit)
            {
                return Some(Side {
                    left: digit == b'0',
                    key: key(at, prefix.len() + 1),
                });
            }
        }
    }
    None
}

/// Pairs the files of one folder by the camera in their names; the pairs in natural order
/// of their names, and every file left out with its reason.
pub fn pair_one_folder(files: &[PathBuf]) -> (Vec<FramePair>, Vec<Unpaired>) {
    let mut sides = Vec::new();
    let mut unpaired = Vec::new();
    for path in files {
        match side_of(&file_name(path)) {
            Some(side) => sides.push((side.key, side.left, path.clone())),
            None => unpaired.push(Unpaired {
                path: path.clone(),
                reason: "its name names neither camera (left/right, l/r, cam0/cam1, im0/im1)"
                    .to_owned(),
            }),
        }
    }
    let (pairs, more) = match_up(sides);
    unpaired.extend(more);
    (pairs, unpaired)
}

/// Pairs the files of a left and a right folder: by the same name, else by the same name but
/// for the camera named in it.
pub fn pair_two_folders(left: &[PathBuf], right: &[PathBuf]) -> (Vec<FramePair>, Vec<Unpaired>) {
    let key = |path: &PathBuf| {
        let name = file_name(path);
        side_of(&name).map_or_else(|| stem(path).to_lowercase(), |s| s.key)
    };
    let sides = left
        .iter()
        .map(|p| (key(p), true, p.clone()))
        .chain(right.iter().map(|p| (key(p), false, p.clone())))
        .collect();
    match_up(sides)
}

/// Pairs `(key, is_left, path)` entries with the same key.
fn match_up(mut sides: Vec<(String, bool, PathBuf)>) -> (Vec<FramePair>, Vec<Unpaired>) {
    sides.sort_by(|a, b| natural(&a.0, &b.0).then(b.1.cmp(&a.1)).then(a.2.cmp(&b.2)));
    let mut pairs = Vec::new();
    let mut unpaired = Vec::new();
    let mut i = 0;
    while i < sides.len() {
        let mut j = i;
        while j < sides.len() && sides[j].0 == sides[i].0 {
            j += 1;
        }
        let group = &sides[i..j];
        let lefts: Vec<&PathBuf> = group.iter().filter(|s| s.1).map(|s| &s.2).collect();
        let rights: Vec<&PathBuf> = group.iter().filter(|s| !s.1).map(|s| &s.2).collect();
        match (lefts.as_slice(), rights.as_slice()) {
            ([l], [r]) => pairs.push(FramePair {
                name: stem(l),
                left: (*l).clone(),
                right: (*r).clone(),
            }),
            (ls, rs) => {
                for (path, partner) in ls
                    .iter()
                    .map(|p| (p, "right"))
                    .chain(rs.iter().map(|p| (p, "left")))
                {
                    let reason = if ls.len() > 1 || rs.len() > 1 {
                        format!(
                            "{} left and {} right frames share its name: which is its partner?",
                            ls.len(),
                            rs.len()
                        )
                    } else {
                        format!("no {partner} frame of the same name")
                    };
                    unpaired.push(Unpaired {
                        path: (*path).clone(),
                        reason,
                    });
                }
            }
        }
        i = j;
    }
    pairs.sort_by(|a, b| natural(&a.name, &b.name));
    (pairs, unpaired)
}

/// The file's name, without its folder (empty for a path without one).
pub fn file_name(path: &Path) -> String {
    path.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

fn stem(path: &Path) -> String {
    path.file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
}

/// Natural order: runs of digits compared as numbers, so `frame2` comes before `frame10`.
pub fn natural(a: &str, b: &str) -> Ordering {
    let (mut a, mut b) = (a.as_bytes(), b.as_bytes());
    loop {
        match (a.first(), b.first()) {
            (None, None) => return Ordering::Equal,
            (None, _) => return Ordering::Less,
            (_, None) => return Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let run = |s: &[u8]| s.iter().take_while(|c| c.is_ascii_digit()).count();
                let (na, nb) = (run(a), run(b));
                let (da, db) = (&a[..na], &b[..nb]);
                let trim = |d: &[u8]| {
                    let zeros = d.iter().take_while(|&&c| c == b'0').count();
                    d[zeros..].to_vec()
                };
                let (ta, tb) = (trim(da), trim(db));
                let order = ta.len().cmp(&tb.len()).then(ta.cmp(&tb)).then(na.cmp(&nb));
                if order != Ordering::Equal {
                    return order;
                }
                (a, b) = (&a[na..], &b[nb..]);
            }
            (Some(x), Some(y)) => {
                if x != y {
                    return x.cmp(y);
                }
                (a, b) = (&a[1..], &b[1..]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The page's rules: the word, a lone letter, a numbered camera; the key is the rest.
    #[test]
    fn the_camera_is_read_from_the_name() {
        let side = |n: &str| side_of(n).map(|s| (s.left, s.key));
        assert_eq!(side("Left_0001.PNG"), Some((true, "*_0001".into())));
        assert_eq!(
            side("frame_right_0001.jpg"),
            Some((false, "frame_*_0001".into()))
        );
        assert_eq!(side("0001_l.png"), Some((true, "0001_*".into())));
        assert_eq!(side("im1.png"), Some((false, "*".into())));
        assert_eq!(side("cam0_17.jpeg"), Some((true, "*_17".into())));
        assert_eq!(side("image_1-5.png"), Some((false, "*-5".into())));
        assert_eq!(side("world.png"), None);
        assert_eq!(side("cam10.png"), None);
    }

    /// One folder: pairs by the camera, in natural order; a lone frame and a nameless one
    /// are each named with their reason.
    #[test]
    fn one_folder_pairs_by_camera() {
        let files: Vec<PathBuf> = [
            "left_10.png",
            "right_10.png",
            "left_9.png",
            "right_9.png",
            "left_11.png",
            "notes.png",
        ]
        .iter()
        .map(PathBuf::from)
        .collect();
        let (pairs, unpaired) = pair_one_folder(&files);
        let names: Vec<&str> = pairs.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["left_9", "left_10"]);
        assert_eq!(pairs[0].right, PathBuf::from("right_9.png"));
        let lost: Vec<(String, &str)> = unpaired
            .iter()
            .map(|u| (u.path.display().to_string(), u.reason.as_str()))
            .collect();
        assert_eq!(lost.len(), 2);
        assert!(lost.contains(&("left_11.png".into(), "no right frame of the same name")));
        assert!(
            lost[0].1.contains("names neither camera")
                || lost[1].1.contains("names neither camera")
        );
    }

    /// Two folders: the same name, or the same but for the camera.
    #[test]
    fn two_folders_pair_by_name() {
        let l: Vec<PathBuf> = ["l/0001.png", "l/0002.png", "l/cam0_3.png"]
            .iter()
            .map(PathBuf::from)
            .collect();
        let r: Vec<PathBuf> = ["r/0001.png", "r/cam1_3.png", "r/0004.png"]
            .iter()
            .map(PathBuf::from)
            .collect();
        let (pairs, unpaired) = pair_two_folders(&l, &r);
        let names: Vec<&str> = pairs.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["0001", "cam0_3"]);
        let lost: Vec<String> = unpaired
            .iter()
            .map(|u| u.path.display().to_string())
            .collect();
        assert_eq!(lost, ["l/0002.png", "r/0004.png"]);
    }

    #[test]
    fn natural_order_reads_numbers() {
        let mut names = vec!["f10", "f9", "f010", "f1", "g"];
        names.sort_by(|a, b| natural(a, b));
        assert_eq!(names, ["f1", "f9", "f10", "f010", "g"]);
    }
}
