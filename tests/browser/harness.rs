//! The page object of the browser tests: chromedriver as a child process, a headless
//! Chromium session against the real server on 127.0.0.1, and the reads, waits and actions
//! the tests are written in.

use std::{
    net::TcpListener,
    path::PathBuf,
    process::{Child, Command, Stdio},
    time::{Duration, Instant, SystemTime, UNIX_EPOCH},
};

use fantoccini::{
    Client, ClientBuilder, Locator,
    actions::{InputSource, MouseActions, PointerAction},
    elements::Element,
    wd::{Capabilities, WebDriverCompatibleCommand},
};
use hyper_util::client::legacy::connect::HttpConnector;
use serde_json::{Value, json};
use stereo_distance::{Application, Config, config::HeavyLimits};

/// A bound on waiting for something that must happen, so a bug fails instead of hanging. It is
/// never what a test asserts.
pub const PATIENCE: Duration = Duration::from_secs(30);

/// The image requests' time limit in the tests' server. The default 30 s protects a release
/// server; a debug build's calibration of the sample's 13 pairs with cross-validation takes
/// 15-35 s of CPU on a 2-core machine (34 s measured), so the page's 503 would be the test's
/// answer. The page's waits for a calibration are longer still.
pub const HEAVY_PATIENCE: Duration = Duration::from_secs(150);

/// The configuration of the tests' server: port 0, and [`HEAVY_PATIENCE`] for image requests.
pub fn test_config() -> Config {
    let config = Config::default();
    Config {
        port: 0,
        heavy: HeavyLimits {
            request_timeout: HEAVY_PATIENCE,
            ..config.heavy
        },
        ..config
    }
}

pub fn path_from(var: &str, default: &str) -> String {
    std::env::var(var).unwrap_or_else(|_| default.to_owned())
}

pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// chromedriver as a child process, killed when dropped.
pub struct Driver(Child);

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// W3C WebDriver "Set Permission" (chromedriver implements it): lets the page read the
/// clipboard, so a test can check what "Copy results" put there.
#[derive(Debug)]
pub struct SetPermission(pub &'static str);

impl WebDriverCompatibleCommand for SetPermission {
    fn endpoint(
        &self,
        base_url: &url::Url,
        session_id: Option<&str>,
    ) -> Result<url::Url, url::ParseError> {
        base_url.join(&format!("session/{}/permissions", session_id.unwrap_or("")))
    }

    fn method_and_body(&self, _: &url::Url) -> (axum::http::Method, Option<String>) {
        let body = json!({"descriptor": {"name": self.0}, "state": "granted"});
        (axum::http::Method::POST, Some(body.to_string()))
    }
}

/// chromedriver's log command (`se/log`, type `browser`): the console's messages since the
/// last call, CSP violations and uncaught errors among them (level `SEVERE`).
#[derive(Debug)]
pub struct BrowserLog;

impl WebDriverCompatibleCommand for BrowserLog {
    fn endpoint(
        &self,
        base_url: &url::Url,
        session_id: Option<&str>,
    ) -> Result<url::Url, url::ParseError> {
        base_url.join(&format!("session/{}/se/log", session_id.unwrap_or("")))
    }

    fn method_and_body(&self, _: &url::Url) -> (axum::http::Method, Option<String>) {
        (
            axum::http::Method::POST,
            Some(json!({"type": "browser"}).to_string()),
        )
    }
}

/// Chromium's arguments for its fake camera playing `y4m` (looped) to `getUserMedia`, the
/// permission granted.
pub fn fake_camera(y4m: &std::path::Path) -> [String; 3] {
    [
        "--use-fake-ui-for-media-stream".to_owned(),
        "--use-fake-device-for-media-stream".to_owned(),
        format!("--use-file-for-fake-video-capture={}", y4m.display()),
    ]
}

/// A served application, a chromedriver and one browser session.
pub struct Browser {
    pub client: Client,
    pub base: String,
    profile: PathBuf,
    _driver: Driver,
    _server: tokio::task::JoinHandle<std::io::Result<()>>,
}

impl Browser {
    /// Starts the server on a free port, chromedriver, and headless Chromium with a window of
    /// `width`×`height`.
    pub async fn start(width: u32, height: u32) -> Browser {
        Self::start_with(width, height, None).await
    }

    /// As [`Browser::start`], emulating a phone's screen of `width`×`height` CSS pixels (a
    /// headless window cannot be narrower than 500 px).
    pub async fn phone(width: u32, height: u32) -> Browser {
        let metrics = json!({"deviceMetrics": {"width": width, "height": height, "pixelRatio": 2}});
        Self::start_with(500, height, Some(metrics)).await
    }

    pub async fn start_with(width: u32, height: u32, mobile: Option<Value>) -> Browser {
        Self::serving(test_config(), width, height, mobile).await
    }

    /// As [`Browser::start`], Chromium's fake camera playing `y4m` (a Y4M file, looped) to
    /// `getUserMedia`, its permission granted.
    pub async fn with_camera(y4m: &std::path::Path, width: u32, height: u32) -> Browser {
        Self::serving_with(test_config(), width, height, None, &fake_camera(y4m)).await
    }

    /// As [`Browser::start_with`], the server started with `config` (port 0).
    pub async fn serving(
        config: Config,
        width: u32,
        height: u32,
        mobile: Option<Value>,
    ) -> Browser {
        Self::serving_with(config, width, height, mobile, &[]).await
    }

    /// As [`Browser::serving`], with Chromium given `extra` arguments too.
    pub async fn serving_with(
        config: Config,
        width: u32,
        height: u32,
        mobile: Option<Value>,
        extra: &[String],
    ) -> Browser {
        let application = Application::build(config).await.expect("the server binds");
        let base = format!("http://{}", application.local_addr().expect("bound"));
        let server = tokio::spawn(application.run_until(std::future::pending()));

        let port = free_port();
        let driver = Command::new(path_from("CHROMEDRIVER", "/usr/bin/chromedriver"))
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver starts (install Debian's chromium-driver)");
        let driver = Driver(driver);
        let webdriver = format!("http://127.0.0.1:{port}");

        let stamp = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let profile =
            std::env::temp_dir().join(format!("stereo-e2e-profile-{}-{stamp}", std::process::id()));
        let mut capabilities = Capabilities::new();
        capabilities.insert("browserName".into(), json!("chrome"));
        let mut options = json!({
                "binary": path_from("CHROMIUM", "/usr/bin/chromium"),
                "args": [
                    "--headless",
                    "--no-sandbox",
                    "--disable-gpu",
                    "--disable-background-networking",
                    "--disable-component-update",
                    "--disable-sync",
                    "--no-first-run",
                    format!("--user-data-dir={}", profile.display()),
                    format!("--window-size={width},{height}"),
                ],
        });
        if let Some(args) = options["args"].as_array_mut() {
            args.extend(extra.iter().map(|a| json!(a)));
        }
        if let Some(mobile) = mobile {
            options["mobileEmulation"] = mobile;
        }
        capabilities.insert("goog:chromeOptions".into(), options);
        capabilities.insert("goog:loggingPrefs".into(), json!({"browser": "ALL"}));
        // chromedriver needs a moment to listen; retry the session until it does.
        let started = Instant::now();
        let client = loop {
            match ClientBuilder::new(HttpConnector::new())
                .capabilities(capabilities.clone())
                .connect(&webdriver)
                .await
            {
                Ok(client) => break client,
                Err(error) if started.elapsed() < PATIENCE => {
                    let _ = error;
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
                Err(error) => panic!("no WebDriver session from chromedriver: {error}"),
            }
        };
        Browser {
            client,
            base,
            profile,
            _driver: driver,
            _server: server,
        }
    }

    /// A desktop-sized browser on `/` as a first visit sees it: the defaults computed, 105 mm.
    pub async fn at_defaults() -> Browser {
        let browser = Browser::start(1280, 1400).await;
        browser.open("/").await;
        browser.until_text("distance", "105 mm").await;
        browser
    }

    /// Opens `path` and waits until the page has shown its first answer.
    pub async fn open(&self, path: &str) {
        self.client
            .goto(&format!("{}{path}", self.base))
            .await
            .expect("the page loads");
        self.settled().await;
    }

    pub async fn find(&self, id: &str) -> Element {
        self.client
            .find(Locator::Id(id))
            .await
            .unwrap_or_else(|e| panic!("#{id} is on the page: {e}"))
    }

    pub async fn text(&self, id: &str) -> String {
        self.find(id)
            .await
            .text()
            .await
            .expect("text")
            .trim()
            .to_owned()
    }

    pub async fn value(&self, id: &str) -> String {
        self.find(id)
            .await
            .prop("value")
            .await
            .expect("value")
            .unwrap_or_default()
    }

    pub async fn attr(&self, id: &str, name: &str) -> Option<String> {
        self.find(id).await.attr(name).await.expect("attribute")
    }

    /// Chooses the option with `value` in the select `#id`.
    /// Attribute `name` of the first element matching the CSS selector `css`.
    pub async fn attr_css(&self, css: &str, name: &str) -> Option<String> {
        self.client
            .find(Locator::Css(css))
            .await
            .unwrap_or_else(|e| panic!("{css}: {e}"))
            .attr(name)
            .await
            .expect("an attribute read")
    }

    pub async fn choose(&self, id: &str, value: &str) {
        self.find(id)
            .await
            .select_by_value(value)
            .await
            .unwrap_or_else(|e| panic!("#{id} offers {value}: {e}"));
    }

    /// Opens the folded section `#id` (a `<details>`) by clicking its summary, as a person
    /// would, unless it is open.
    pub async fn unfold(&self, id: &str) {
        if self.attr(id, "open").await.is_none() {
            self.client
                .find(Locator::Css(&format!("#{id} > summary")))
                .await
                .unwrap_or_else(|e| panic!("#{id} has a summary: {e}"))
                .click()
                .await
                .expect("click");
        }
    }

    /// The top and bottom of `#id` in the viewport, and the viewport's height, in CSS pixels.
    pub async fn place(&self, id: &str) -> (f64, f64, f64) {
        let got = self
            .script(&format!(
                "const r = document.getElementById('{id}').getBoundingClientRect(); \
                 return [r.top, r.bottom, window.innerHeight]"
            ))
            .await;
        let at = |i: usize| got[i].as_f64().expect("a number");
        (at(0), at(1), at(2))
    }

    /// Clears a text field and types `text` into it, as a person would.
    pub async fn type_into(&self, id: &str, text: &str) {
        let field = self.find(id).await;
        field.clear().await.expect("clear");
        field.send_keys(text).await.expect("type");
    }

    pub async fn script(&self, source: &str) -> Value {
        self.client
            .execute(source, vec![])
            .await
            .unwrap_or_else(|e| panic!("script {source}: {e}"))
    }

    /// Waits until the page is not computing and no typing is pending, then checks that
    /// nothing it hides is displayed.
    pub async fn settled(&self) {
        self.until_done("state").await;
        self.assert_hidden_not_shown().await;
    }

    /// Every element with the `hidden` attribute is not displayed: a class's `display` must
    /// not override it. Names (by id, or tag) those that are.
    pub async fn assert_hidden_not_shown(&self) {
        let shown = self
            .script(
                "return [...document.querySelectorAll('[hidden]')]\
                 .filter((e) => getComputedStyle(e).display !== 'none')\
                 .map((e) => e.id || e.tagName)",
            )
            .await;
        assert_eq!(shown, json!([]), "hidden elements displayed");
    }

    /// Waits until the page's `data-{flag}` on `<body>` reads `done`: the work it tracks (the
    /// numbers, the depth map, a match) has come back and none is pending.
    pub async fn until_done(&self, flag: &str) {
        self.until(&format!("body's data-{flag} to be done"), || async {
            let state = self
                .script(&format!("return document.body.dataset.{flag} || ''"))
                .await;
            (state == "done").then_some(())
        })
        .await;
    }

    /// Polls `probe` until it gives a value; panics naming `what` after [`PATIENCE`].
    pub async fn until<T, F, Fut>(&self, what: &str, probe: F) -> T
    where
        F: FnMut() -> Fut,
        Fut: std::future::Future<Output = Option<T>>,
    {
        self.until_within(what, PATIENCE, probe).await
    }

    /// As [`Browser::until`], with a bound of its own: a calibration in a debug build (the
    /// corners of 26 images found by unoptimised code) takes longer than a click.
    pub async fn until_within<T, F, Fut>(&self, what: &str, patience: Duration, mut probe: F) -> T
    where
        F: FnMut() -> Fut,
        Fut: std::future::Future<Output = Option<T>>,
    {
        let started = Instant::now();
        loop {
            if let Some(value) = probe().await {
                return value;
            }
            assert!(started.elapsed() < patience, "timed out waiting for {what}");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    /// Waits until `#id`'s text is `expected`, and returns it.
    pub async fn until_text(&self, id: &str, expected: &str) -> String {
        self.until(&format!("#{id} to read {expected:?}"), || async {
            let text = self.text(id).await;
            (text == expected).then_some(text)
        })
        .await
    }

    /// Saves a screenshot of the window as an artifact and returns its path.
    pub async fn screenshot(&self, name: &str) -> PathBuf {
        let dir = std::env::var_os("E2E_ARTIFACTS").map_or_else(
            || PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("e2e"),
            PathBuf::from,
        );
        std::fs::create_dir_all(&dir).expect("artifact folder");
        let png = self.client.screenshot().await.expect("screenshot");
        assert!(png.starts_with(b"\x89PNG"), "a PNG image");
        let path = dir.join(name);
        std::fs::write(&path, png).expect("screenshot written");
        eprintln!("screenshot: {}", path.display());
        path
    }

    /// The console's errors since the last call (CSP violations, uncaught exceptions, failed
    /// loads), as chromedriver reports them.
    pub async fn console_errors(&self) -> Vec<String> {
        let log = self
            .client
            .issue_cmd(BrowserLog)
            .await
            .expect("chromedriver's browser log");
        log.as_array()
            .expect("a list of entries")
            .iter()
            .filter(|entry| entry["level"] == "SEVERE")
            .map(|entry| entry["message"].as_str().unwrap_or_default().to_owned())
            .collect()
    }

    /// The paths of every request the page made (the page itself, its assets and each API
    /// call), from the Resource Timing entries, with the origin each was sent to.
    pub async fn requests(&self) -> Vec<(String, String)> {
        let entries = self
            .script(
                "return [location.href, ...performance.getEntriesByType('resource').map(e => e.name)]                   .map(u => new URL(u)).map(u => [u.origin, u.pathname])",
            )
            .await;
        serde_json::from_value(entries).expect("origin and path pairs")
    }

    /// Moves the pointer over the image pixel (`x`, `y`) (its centre) of the element `#id`,
    /// whose canvas holds the image at its own size and is shown scaled to the element. The
    /// element is scrolled into view and the pointer placed in the window's coordinates, to
    /// the nearest CSS pixel: an offset from the element's centre would be rounded twice (the
    /// centre and the offset), which at a fractional layout position lands a pixel or two off.
    pub async fn pointer_to(&self, id: &str, x: f64, y: f64) -> PointerAction {
        let geometry = self
            .script(&format!(
                "const f = document.getElementById('{id}'); \
                 f.scrollIntoView({{block: 'center', inline: 'center'}}); \
                 const c = f.querySelector('canvas'); const r = f.getBoundingClientRect(); \
                 return [r.left, r.top, r.width, r.height, c.width, c.height];"
            ))
            .await;
        let [left, top, width, height, w, h]: [f64; 6] =
            serde_json::from_value(geometry).expect("the element's geometry");
        PointerAction::MoveTo {
            duration: None,
            x: (left + (x + 0.5) * width / w).round(),
            y: (top + (y + 0.5) * height / h).round(),
        }
    }

    /// Performs pointer `steps` with the mouse, then releases everything.
    pub async fn mouse(&self, steps: Vec<PointerAction>) {
        let actions = steps
            .into_iter()
            .fold(MouseActions::new("mouse".to_owned()), |a, step| {
                a.then(step)
            });
        self.client
            .perform_actions(actions)
            .await
            .expect("pointer actions");
        self.client.release_actions().await.expect("release");
    }

    /// Clicks the image pixel (`x`, `y`) of the element `#id`.
    pub async fn click_pixel(&self, id: &str, x: f64, y: f64) {
        let at = self.pointer_to(id, x, y).await;
        self.mouse(vec![
            at,
            PointerAction::Down {
                button: fantoccini::actions::MOUSE_BUTTON_LEFT,
            },
            PointerAction::Up {
                button: fantoccini::actions::MOUSE_BUTTON_LEFT,
            },
        ])
        .await;
    }

    /// Clicks "Copy results" (with the clipboard allowed) and returns what it put there.
    pub async fn copy_results(&self) -> String {
        self.client
            .issue_cmd(SetPermission("clipboard-read"))
            .await
            .expect("clipboard permission");
        self.find("copy").await.click().await.expect("click");
        self.until_text("status", "Copied the results to the clipboard.")
            .await;
        let copied = self
            .client
            .execute_async(
                "const done = arguments[arguments.length - 1];\
                 navigator.clipboard.readText().then(done, e => done('error: ' + e));",
                vec![],
            )
            .await
            .expect("clipboard read");
        copied.as_str().expect("text").to_owned()
    }

    /// Nothing scrolls sideways: the document is no wider than the window.
    pub async fn assert_no_sideways_scroll(&self) {
        let overflow = self
            .script("return document.documentElement.scrollWidth - window.innerWidth")
            .await;
        assert!(
            overflow.as_i64().is_some_and(|o| o <= 0),
            "scrolls sideways by {overflow}"
        );
    }

    /// No alert box is open: the page reports errors inline only.
    pub async fn assert_no_alert(&self) {
        assert!(
            self.client.get_alert_text().await.is_err(),
            "the page opened an alert box"
        );
    }

    pub async fn close(self) {
        let _ = self.client.close().await;
        let _ = std::fs::remove_dir_all(&self.profile);
    }
}

/// Parses an SVG `points` attribute into (x, y) pairs.
pub fn vertices(points: &str) -> Vec<(f64, f64)> {
    points
        .split_whitespace()
        .map(|pair| {
            let (x, y) = pair.split_once(',').expect("x,y");
            (x.parse().expect("x"), y.parse().expect("y"))
        })
        .collect()
}
