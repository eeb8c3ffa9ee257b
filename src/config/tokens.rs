//! Bearer tokens as the settings give them: the `API_TOKENS` list and the tokens file read and
//! checked (what a token may be), before the server starts and each time the file is read
//! again. Kept here, below the server, which holds them as digests (`server::auth`).

use std::path::Path;

/// The shortest token accepted: 16 characters (96 bits as base64), so that no token can be
/// guessed by trying.
pub const MIN_TOKEN_LEN: usize = 16;
/// The longest token accepted.
pub const MAX_TOKEN_LEN: usize = 512;

/// Tokens as given (the `API_TOKENS` variable), shown only as a count.
#[derive(Clone, PartialEq, Eq)]
pub struct ApiTokens(pub Vec<String>);

impl std::fmt::Debug for ApiTokens {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ApiTokens({} tokens, redacted)", self.0.len())
    }
}

/// The tokens of `text`: separated by commas, spaces or new lines, `#` starting a comment to
/// the end of its line. Each is 16 to 512 characters of token68 (RFC 7235: letters, digits
/// and `-._~+/`, `=` at the end); a fault names the token by its place, never by itself.
pub fn parse_tokens(text: &str) -> Result<Vec<String>, String> {
    let mut tokens = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or_default();
        for token in line.split([',', ' ', '\t', '\r']).filter(|t| !t.is_empty()) {
            let place = tokens.len() + 1;
            let body = token.trim_end_matches('=');
            let allowed = |c: char| c.is_ascii_alphanumeric() || "-._~+/".contains(c);
            if !body.chars().all(allowed) || body.is_empty() {
                return Err(format!(
                    "token {place} has characters a bearer token cannot carry (letters, \
                     digits and -._~+/ with = at the end)"
                ));
            }
            if !(MIN_TOKEN_LEN..=MAX_TOKEN_LEN).contains(&token.len()) {
                return Err(format!(
                    "token {place} is {} characters; tokens are {MIN_TOKEN_LEN} to \
                     {MAX_TOKEN_LEN} (make one with `openssl rand -base64 32`)",
                    token.len()
                ));
            }
            tokens.push(token.to_owned());
        }
    }
    if tokens.is_empty() {
        return Err("no token given".to_owned());
    }
    Ok(tokens)
}

/// The tokens of the file at `path`, and its bytes (to tell when it changes).
pub fn read_tokens_file(path: &Path) -> Result<(Vec<String>, Vec<u8>), String> {
    let bytes = std::fs::read(path)
        .map_err(|e| format!("cannot read the tokens file {}: {e}", path.display()))?;
    let tokens = tokens_of_file(&bytes, path)?;
    Ok((tokens, bytes))
}

/// The tokens of a tokens file's `bytes` (the file at `path`, for the message).
pub fn tokens_of_file(bytes: &[u8], path: &Path) -> Result<Vec<String>, String> {
    let text = std::str::from_utf8(bytes)
        .map_err(|_| format!("the tokens file {} is not UTF-8 text", path.display()))?;
    parse_tokens(text).map_err(|e| format!("the tokens file {}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: &str = "alpha-token-0123456789";
    const B: &str = "bravo/token+0123456789==";

    /// Tokens are read from commas, spaces and lines with comments; short ones, ones with
    /// characters a header cannot carry and none at all are refused, naming the place and
    /// never the token.
    #[test]
    fn tokens_are_parsed_and_refused_by_place() {
        let text = format!("# rotated 2026-11\n{A}, {B}\n\n  # old one gone\n");
        assert_eq!(parse_tokens(&text).unwrap(), [A, B]);
        let short = parse_tokens("abc,short").unwrap_err();
        assert!(short.contains("token 1 is 3 characters"), "{short}");
        let odd = parse_tokens(&format!("{A} caf\u{e9}-0123456789abcdef")).unwrap_err();
        assert!(odd.starts_with("token 2 has characters"), "{odd}");
        assert!(!odd.contains("caf"), "{odd}");
        assert_eq!(parse_tokens(" # nothing\n").unwrap_err(), "no token given");
        assert_eq!(
            format!("{:?}", ApiTokens(vec![A.to_owned()])),
            "ApiTokens(1 tokens, redacted)"
        );
    }
}
