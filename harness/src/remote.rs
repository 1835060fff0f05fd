//! The HTTP client of remote builds (`--build-url`, LPC §3: "over HTTP/1.1 range requests
//! with persistent connections"): [`HttpFile`] fetches a whole small file (an index, a
//! manifest) or one byte range of a large one, and is the [`RemoteFile`] through which
//! `methods` reads a remote repository ([`methods::store::remote::RemoteSource`] verifies
//! each chunk as a local read would).
//!
//! The client is [`ureq`] without TLS (builds are served on loopback or a lab network; see
//! `splatbench serve`): its agent keeps connections alive and reuses them, so consecutive
//! chunks travel over one connection per request in flight (the loader's `in_flight`).
//! Every answer is checked before its bytes are used: a range must come back `206` with the
//! `Content-Range` asked for and exactly that many bytes (a server that ignores `Range` and
//! sends the whole file is an error, not a download of the whole repository); a whole file
//! must come back `200`. Any other status, a connection refused or reset, a short body, or no
//! answer within the timeout is a [`MethodError::Remote`] naming the URL.

use std::sync::Arc;
use std::time::Duration;

use methods::MethodError;
use methods::store::remote::RemoteFile;
use methods::store::source::MAX_IN_FLIGHT;

/// How long one request may take, connection to last byte, unless set otherwise.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(30);

/// The largest whole file [`RemoteFile::get`] reads (indices and manifests are far smaller;
/// a larger answer is refused before it fills memory).
pub const WHOLE_FILE_MAX: u64 = 1 << 30;

/// One file at a URL, read through a keep-alive agent.
#[derive(Clone)]
pub struct HttpFile {
    agent: ureq::Agent,
    url: String,
    timeout: Duration,
}

impl HttpFile {
    /// The file at `url`; each request may take at most `timeout`.
    pub fn new(url: impl Into<String>, timeout: Duration) -> Self {
        let config = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(timeout))
            // Every request in flight keeps its connection for the next (ureq keeps 3 per
            // host by default, which would reconnect the fourth of four in flight each time).
            .max_idle_connections_per_host(MAX_IN_FLIGHT as usize)
            .max_idle_connections(MAX_IN_FLIGHT as usize)
            .build();
        Self {
            agent: ureq::Agent::new_with_config(config),
            url: url.into(),
            timeout,
        }
    }

    /// The same agent (and its open connections) reading another URL.
    pub fn sibling(&self, url: impl Into<String>) -> Self {
        Self {
            agent: self.agent.clone(),
            url: url.into(),
            timeout: self.timeout,
        }
    }

    /// The URL.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// What went wrong with a request, a timeout said in words with the time allowed.
    fn failure(&self, e: &ureq::Error) -> String {
        match e {
            ureq::Error::Timeout(_) => format!(
                "no answer within {:.1} s (timed out)",
                self.timeout.as_secs_f64()
            ),
            e => e.to_string(),
        }
    }

    fn error(&self, msg: impl Into<String>) -> MethodError {
        MethodError::Remote {
            url: self.url.clone(),
            msg: msg.into(),
        }
    }

    /// The whole file (`200 OK`, at most [`WHOLE_FILE_MAX`] bytes).
    pub fn get(&self) -> Result<Vec<u8>, MethodError> {
        let mut resp = self
            .agent
            .get(&self.url)
            .call()
            .map_err(|e| self.error(format!("request failed: {}", self.failure(&e))))?;
        let status = resp.status().as_u16();
        if status != 200 {
            return Err(self.error(format!("HTTP {status}, expected 200")));
        }
        resp.body_mut()
            .with_config()
            .limit(WHOLE_FILE_MAX)
            .read_to_vec()
            .map_err(|e| self.error(format!("reading the body: {}", self.failure(&e))))
    }

    /// Bytes `start..start + len` (`len ≥ 1`): a `206` answer with exactly that range.
    pub fn get_range(&self, start: u64, len: u64) -> Result<Vec<u8>, MethodError> {
        if len == 0 {
            return Ok(Vec::new());
        }
        let last = start
            .checked_add(len - 1)
            .ok_or_else(|| self.error(format!("range {start}..+{len} overflows")))?;
        let mut resp = self
            .agent
            .get(&self.url)
            .header("Range", format!("bytes={start}-{last}"))
            .call()
            .map_err(|e| {
                self.error(format!(
                    "request for bytes {start}-{last} failed: {}",
                    self.failure(&e)
                ))
            })?;
        let status = resp.status().as_u16();
        if status != 206 {
            return Err(self.error(format!(
                "HTTP {status} for bytes {start}-{last}, expected 206 Partial Content"
            )));
        }
        let range = resp
            .headers()
            .get("content-range")
            .and_then(|v| v.to_str().ok())
            .unwrap_or("")
            .to_string();
        let want = format!("bytes {start}-{last}/");
        if !range.starts_with(&want) {
            return Err(self.error(format!(
                "Content-Range {range:?} for bytes {start}-{last}, expected \"{want}…\""
            )));
        }
        let body = resp
            .body_mut()
            .with_config()
            .limit(len + 1)
            .read_to_vec()
            .map_err(|e| {
                self.error(format!(
                    "reading bytes {start}-{last}: {}",
                    self.failure(&e)
                ))
            })?;
        if body.len() as u64 != len {
            return Err(self.error(format!(
                "bytes {start}-{last}: {} bytes received, {len} expected",
                body.len()
            )));
        }
        Ok(body)
    }
}

impl RemoteFile for HttpFile {
    fn url(&self) -> &str {
        HttpFile::url(self)
    }

    fn get(&self) -> Result<Vec<u8>, MethodError> {
        HttpFile::get(self)
    }

    fn get_range(&self, start: u64, len: u64) -> Result<Vec<u8>, MethodError> {
        HttpFile::get_range(self, start, len)
    }
}

/// An opener for [`methods::MethodKind::fetch_remote`]: every file through one agent whose
/// requests may each take `timeout`.
pub fn opener(timeout: Duration) -> impl Fn(&str) -> Arc<dyn RemoteFile> {
    let agent = HttpFile::new("", timeout);
    move |url| Arc::new(agent.sibling(url)) as Arc<dyn RemoteFile>
}
