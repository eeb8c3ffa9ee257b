//! The page against a service that takes bearer tokens: it asks for a token once, in its
//! dialog, when the service first answers 401; a token refused is asked for again, saying so;
//! the token given is kept for the tab (a reload asks nothing) and sent with every request.

use stereo_distance::Config;
use stereo_distance::config::ApiTokens;

use crate::harness::{Browser, test_config};

const TOKEN: &str = "page-token-0123456789abcdef";

impl Browser {
    /// Waits until the token dialog is open, and gives its message.
    pub(crate) async fn token_asked(&self) -> String {
        self.until("the token dialog", || async {
            let open = self
                .script("return document.getElementById('token-dialog').open")
                .await;
            (open == true).then_some(())
        })
        .await;
        self.text("token-why").await
    }

    /// Types `token` into the dialog and submits it.
    pub(crate) async fn give_token(&self, token: &str) {
        self.type_into("token-input", token).await;
        self.find("token-use").await.click().await.expect("clicked");
    }
}

/// A first visit: the dialog asks for a token (the page's first /distance was refused); a
/// wrong one is refused and asked for again; the right one gives the page its answer (105 mm).
/// A reload in the same tab asks nothing and shows the answer; the token sits in the tab's
/// sessionStorage, not in localStorage.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn the_page_asks_for_a_token_once_and_keeps_it_for_the_tab() {
    // Arrange
    let config = Config {
        api_tokens: Some(ApiTokens(vec![TOKEN.to_owned()])),
        ..test_config()
    };
    let browser = Browser::serving(config, 1280, 1400, None).await;

    // Act
    browser
        .client
        .goto(&format!("{}/", browser.base))
        .await
        .expect("the page loads");
    let first = browser.token_asked().await;
    browser.give_token("wrong-token-0123456789").await;
    let again = browser.token_asked().await;
    browser.give_token(TOKEN).await;

    // Assert
    assert!(first.contains("access token only"), "{first}");
    assert!(again.contains("did not accept"), "{again}");
    browser.until_text("distance", "105 mm").await;
    let kept = browser
        .script(
            "return [sessionStorage.getItem('stereo-distance-token'), \
             localStorage.getItem('stereo-distance-token')]",
        )
        .await;
    assert_eq!(kept, serde_json::json!([TOKEN, null]));

    // Act: the same tab, reloaded.
    browser.client.refresh().await.expect("reloaded");
    browser.settled().await;

    // Assert
    browser.until_text("distance", "105 mm").await;
    let open = browser
        .script("return document.getElementById('token-dialog').open")
        .await;
    assert_eq!(open, false);
    browser.assert_clean_but(&["401"]).await;
    browser.close().await;
}
