//! A pair sent to a running service (`--server`): its frames as the `/depth-map` form's
//! files (a ROS `Image`'s pixels as a PNG), sent again after a wait while the service cannot
//! be reached or is unavailable, and a refusal read into the pair's fault or the run's.

use super::engine::Frame;
use super::retry::{self, Policy};
use super::transport::{Answer, Server};
use super::work::{Event, Failure, Pair};

/// What every request of the run carries besides its pair.
pub struct Form {
    pub path_and_query: String,
    /// The rig's parts: `(name, file name, bytes)`.
    pub parts: Vec<(String, Option<String>, Vec<u8>)>,
    pub policy: Policy,
    /// A pair the service warned about fails, and nothing is written for it.
    pub strict: bool,
}

/// `work`'s answer from `server`, with the service's warnings; a refusal as the pair's fault
/// (or the run's, when it would refuse every pair).
pub async fn send(
    server: &mut Server,
    form: &Form,
    work: &Pair,
    frames: [Frame; 2],
    events: &tokio::sync::mpsc::Sender<Event>,
) -> Result<Answer, Failure> {
    let files = frames.map(|f| f.into_file());
    let (left, right) = match files {
        [Ok(l), Ok(r)] => (l, r),
        [Err(e), _] => return Err(Failure::Pair(format!("{}: {e}", work.names[0]))),
        [_, Err(e)] => return Err(Failure::Pair(format!("{}: {e}", work.names[1]))),
    };
    let mut parts: Vec<(&str, Option<String>, &[u8])> = vec![
        ("left", Some(short(&work.names[0])), &left),
        ("right", Some(short(&work.names[1])), &right),
    ];
    for (name, file, bytes) in &form.parts {
        parts.push((name, file.clone(), bytes));
    }
    let (body, content_type) = multipart(&parts);
    let mut retry = 0;
    let answer: Answer = loop {
        let (why, asked) = match server
            .post(&form.path_and_query, &content_type, body.clone())
            .await
        {
            Ok(answer) if retry::retried_status(answer.status) => (
                format!("the service answered {}", status_words(answer.status)),
                answer.retry_after,
            ),
            Ok(answer) => break answer,
            Err(unreachable) => (unreachable, None),
        };
        retry += 1;
        let jitter = f64::from(uuid::Uuid::new_v4().as_u128() as u32) / f64::from(u32::MAX);
        let Some(wait) = form.policy.wait(retry, asked, jitter) else {
            let tries = if retry == 1 {
                "on the only try".to_owned()
            } else {
                format!("on each of {retry} tries")
            };
            return Err(Failure::Run(format!(
                "{why}, {tries} (--retries {})",
                form.policy.retries
            )));
        };
        let _ = events
            .send(Event::Waiting(format!(
                "{why}; sending {} again in {:.1} s (retry {retry} of {})",
                work.name,
                wait.as_secs_f64(),
                form.policy.retries
            )))
            .await;
        tokio::time::sleep(wait).await;
    };
    if answer.status != 200 {
        return Err(refusal(&answer, work));
    }
    Ok(answer)
}

/// The last part of a frame's name (its file's name).
fn short(name: &str) -> String {
    std::path::Path::new(name)
        .file_name()
        .map_or_else(|| name.to_owned(), |n| n.to_string_lossy().into_owned())
}

fn status_words(status: u16) -> String {
    let reason = axum::http::StatusCode::from_u16(status)
        .ok()
        .and_then(|s| s.canonical_reason())
        .unwrap_or("");
    format!("{status} {reason}").trim_end().to_owned()
}

/// What a refusal says, each part named by the frame it is about. The run's settings were
/// checked before the first frame, so a 422 or 413 is the pair's (an image that cannot be
/// read, a frame of another size); so is a 500 or a timeout of this frame's work. A refused
/// token (401, 403) or a request the service does not take (400, 404, 405, 415) would refuse
/// every frame alike: they stop the run.
fn refusal(answer: &Answer, work: &Pair) -> Failure {
    let problem: serde_json::Value = serde_json::from_slice(&answer.body).unwrap_or_default();
    let detail = problem["detail"].as_str().unwrap_or("").to_owned();
    let mut lines = Vec::new();
    for error in problem["errors"].as_array().into_iter().flatten() {
        let field = error["field"].as_str().unwrap_or("");
        let message = error["message"].as_str().unwrap_or("");
        let what = match field {
            "left" => work.names[0].clone(),
            "right" => work.names[1].clone(),
            other => other.to_owned(),
        };
        lines.push(format!("{what}: {message}"));
    }
    let said = if lines.is_empty() {
        format!("{} {detail}", status_words(answer.status))
            .trim_end()
            .to_owned()
    } else {
        lines.join("; ")
    };
    match answer.status {
        400..=407 | 409..=412 | 414..=421 => Failure::Run(format!(
            "the service refused the run ({}): {said}",
            status_words(answer.status)
        )),
        _ => Failure::Pair(said),
    }
}

/// A `multipart/form-data` body of `(name, file name, bytes)` parts, and its content type.
fn multipart(parts: &[(&str, Option<String>, &[u8])]) -> (Vec<u8>, String) {
    let boundary = format!("stereo-distance-{}", uuid::Uuid::new_v4().simple());
    let mut body = Vec::with_capacity(parts.iter().map(|p| p.2.len() + 200).sum());
    for (name, file, bytes) in parts {
        body.extend_from_slice(format!("--{boundary}\r\n").as_bytes());
        match file {
            Some(file) => body.extend_from_slice(
                format!(
                    "Content-Disposition: form-data; name=\"{name}\"; filename=\"{}\"\r\n\
                     Content-Type: application/octet-stream\r\n\r\n",
                    file.replace(['"', '\r', '\n'], "_")
                )
                .as_bytes(),
            ),
            None => body.extend_from_slice(
                format!("Content-Disposition: form-data; name=\"{name}\"\r\n\r\n").as_bytes(),
            ),
        }
        body.extend_from_slice(bytes);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(format!("--{boundary}--\r\n").as_bytes());
    (body, format!("multipart/form-data; boundary={boundary}"))
}
