//! `splatbench serve`: a build directory served over HTTP/1.1 with byte ranges, for the
//! remote runs of LPC, MWKD, Potree and voxel (the LPC paper streams its repository "over
//! HTTP/1.1 range requests with persistent connections"; Potree's viewer reads `octree.bin`
//! a node at a time by ranges) and for experiments on a slow or failing link.
//!
//! The HTTP protocol (request parsing, persistent connections, `Content-Length`, `HEAD`) is
//! [`tiny_http`]'s: a synchronous server, so serving adds no async runtime to the build.
//! This module decides what to answer:
//!
//! - `GET`/`HEAD` of a regular file under the served directory; `405` for other methods;
//! - `Range: bytes=…` ([`range::parse`]): `206` with `Content-Range`, `416` with
//!   `Content-Range: bytes */LEN` past the end, the whole file otherwise; `If-Range` with
//!   another validator than the file's `ETag` gives the whole file (RFC 9110 §13.1.5);
//! - `ETag` (`"LEN-MTIME"`, hexadecimal, nanoseconds) and `Last-Modified` on every file
//!   response, `Accept-Ranges: bytes`; bodies always carry `Content-Length` (never chunked);
//! - paths: percent-decoded, `.` segments dropped; a `..` segment, a backslash or a NUL is
//!   `403`; the file found must lie under the directory once symbolic links are resolved
//!   (`403` otherwise, so a link out of the directory is refused); a directory or a missing
//!   file is `404` (no listings);
//! - experiments ([`ServeOptions`]): a bandwidth shared by all connections
//!   ([`throttle::Link`]), a latency added before each response, and `fail_after`: every
//!   request after the first `N` is answered `500`;
//! - an access log, one line per request: time (Unix seconds), peer, method, target,
//!   range, status, body bytes.

pub mod range;
pub mod throttle;

use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{Context as _, bail};
use tiny_http::{Header, Method, Request, Response, StatusCode};

use range::Ranged;
use throttle::{Link, Paced};

/// How a directory is served.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// The directory served (its files, and those of its subdirectories).
    pub root: PathBuf,
    /// Address to listen on; port 0 takes a free one ([`Server::addr`] tells which).
    pub addr: SocketAddr,
    /// Bytes/s of the link shared by all responses' bodies; `None`: as fast as it goes.
    pub bandwidth: Option<f64>,
    /// Added before each response is sent (on [`ServeOptions::clock`]).
    pub latency: Duration,
    /// Every request after the first `N` is answered `500 Internal Server Error`.
    pub fail_after: Option<u64>,
    /// Requests answered at once (each one a thread; a throttled body holds its thread).
    pub threads: usize,
    /// The clock the bandwidth is paced on: the system's, or a test's manual clock (the
    /// pacing then moves that clock instead of sleeping, so a measured rate is exact).
    pub clock: methods::store::access::Clock,
}

impl ServeOptions {
    /// `root` on `addr`, unthrottled, 8 threads.
    pub fn new(root: impl Into<PathBuf>, addr: SocketAddr) -> Self {
        Self {
            root: root.into(),
            addr,
            bandwidth: None,
            latency: Duration::ZERO,
            fail_after: None,
            threads: 8,
            clock: Default::default(),
        }
    }
}

/// A running server; dropping it (or [`Server::stop`]) stops it and closes its socket.
pub struct Server {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    http: Arc<tiny_http::Server>,
    workers: Vec<std::thread::JoinHandle<()>>,
    /// Whether the listening socket has TCP_NODELAY (read back after setting it).
    nodelay: bool,
}

/// Where the access log goes.
pub type Log = Box<dyn Write + Send>;

impl Server {
    /// Starts serving `opt.root` (which must be a directory), logging to `log`.
    pub fn start(opt: &ServeOptions, log: Log) -> anyhow::Result<Server> {
        if let Some(b) = opt.bandwidth
            && !(b.is_finite() && b > 0.0)
        {
            bail!("bandwidth {b}: must be a positive number of bytes/s");
        }
        let root = opt
            .root
            .canonicalize()
            .with_context(|| format!("{}: cannot serve it", opt.root.display()))?;
        if !root.is_dir() {
            bail!("{}: not a directory", opt.root.display());
        }
        let listener = std::net::TcpListener::bind(opt.addr)
            .with_context(|| format!("cannot listen on {}", opt.addr))?;
        // Without TCP_NODELAY a response's body waits behind its header segment for the
        // client's delayed ACK (Nagle): 43 ms per range request on loopback, measured. Linux
        // gives accepted connections the listening socket's setting (tiny_http does not
        // expose them); elsewhere this is a hint.
        let _ = rustix::net::sockopt::set_tcp_nodelay(&listener, true);
        let nodelay = rustix::net::sockopt::tcp_nodelay(&listener).unwrap_or(false);
        let http = tiny_http::Server::from_listener(listener, None)
            .map_err(|e| anyhow::anyhow!("cannot listen on {}: {e}", opt.addr))?;
        let addr = http
            .server_addr()
            .to_ip()
            .context("the server listens on no IP address")?;
        let http = Arc::new(http);
        let stop = Arc::new(AtomicBool::new(false));
        let shared = Arc::new(Shared {
            root,
            link: opt
                .bandwidth
                .map(|b| Arc::new(Link::with_clock(b, opt.clock.clone()))),
            latency: opt.latency,
            clock: opt.clock.clone(),
            fail_after: opt.fail_after,
            served: AtomicU64::new(0),
            log: Mutex::new(log),
        });
        let workers = (0..opt.threads.max(1))
            .map(|_| {
                let (http, stop, shared) = (http.clone(), stop.clone(), shared.clone());
                std::thread::spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        match http.recv_timeout(Duration::from_millis(50)) {
                            Ok(Some(req)) => shared.answer(req),
                            Ok(None) => {}
                            Err(_) => break,
                        }
                    }
                })
            })
            .collect();
        Ok(Server {
            addr,
            stop,
            http,
            workers,
            nodelay,
        })
    }

    /// Whether the listening socket has TCP_NODELAY, which Linux gives every accepted
    /// connection (see `start`): without it a range response's body waits ≈ 40 ms behind
    /// its header for the client's delayed ACK.
    pub fn tcp_nodelay(&self) -> bool {
        self.nodelay
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The base URL of the served directory, `http://ADDR/`.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// Stops accepting, finishes the requests being answered and closes the listening
    /// socket. Connections kept alive stay open (tiny_http offers no way to close them) and
    /// their next requests go unanswered: a client sees its timeout, as on a half-open
    /// connection after a crash. A server killed as a process (`splatbench serve`) closes
    /// them all.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.http.unblock();
        for w in self.workers.drain(..) {
            // A worker that panicked has nothing left to clean up.
            let _ = w.join();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// What every worker shares.
struct Shared {
    root: PathBuf,
    link: Option<Arc<Link>>,
    latency: Duration,
    /// What the latency waits on ([`ServeOptions::clock`]).
    clock: methods::store::access::Clock,
    fail_after: Option<u64>,
    served: AtomicU64,
    log: Mutex<Log>,
}

/// A response decided, before its body is opened.
struct Answer {
    status: u16,
    headers: Vec<(&'static str, String)>,
    body: Body,
}

enum Body {
    Text(String),
    File { file: File, start: u64, len: u64 },
}

impl Answer {
    fn text(status: u16, msg: impl Into<String>) -> Self {
        Self {
            status,
            headers: vec![("Content-Type", "text/plain; charset=utf-8".into())],
            body: Body::Text(msg.into()),
        }
    }
    fn len(&self) -> u64 {
        match &self.body {
            Body::Text(t) => t.len() as u64,
            Body::File { len, .. } => *len,
        }
    }
}

impl Shared {
    fn answer(&self, req: Request) {
        let n = self.served.fetch_add(1, Ordering::Relaxed);
        let range = header(&req, "Range");
        let answer = match self.fail_after {
            Some(limit) if n >= limit => Answer::text(
                500,
                format!("this server fails every request after the first {limit} (--fail-after)\n"),
            ),
            _ => self.decide(&req),
        };
        if !self.latency.is_zero() {
            self.clock.sleep_until(self.clock.now() + self.latency);
        }
        let line = format!(
            "{:.3} {} {} {} {} {} {}\n",
            SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .unwrap_or_default()
                .as_secs_f64(),
            req.remote_addr().map_or("-".into(), |a| a.to_string()),
            req.method(),
            req.url(),
            range.as_deref().unwrap_or("-"),
            answer.status,
            answer.len()
        );
        let sent = self.send(req, answer);
        let mut log = self.log.lock().unwrap_or_else(|p| p.into_inner());
        // The log is best effort: a full disk must not stop the serving.
        let _ = log.write_all(line.as_bytes());
        if let Err(e) = sent {
            let _ = writeln!(log, "  (response not completed: {e})");
        }
        let _ = log.flush();
    }

    fn send(&self, req: Request, a: Answer) -> std::io::Result<()> {
        let len = a.len();
        let mut headers: Vec<Header> = a
            .headers
            .iter()
            .filter_map(|(k, v)| Header::from_bytes(k.as_bytes(), v.as_bytes()).ok())
            .collect();
        headers.extend(Header::from_bytes(&b"Accept-Ranges"[..], &b"bytes"[..]).ok());
        let status = StatusCode(a.status);
        let body: Box<dyn Read + Send> = match a.body {
            Body::Text(t) => Box::new(std::io::Cursor::new(t.into_bytes())),
            Body::File {
                mut file, start, ..
            } => {
                file.seek(SeekFrom::Start(start))?;
                let taken = file.take(len);
                match &self.link {
                    Some(link) => Box::new(Paced::new(taken, link.clone())),
                    None => Box::new(taken),
                }
            }
        };
        let response = Response::new(status, headers, body, Some(len as usize), None)
            .with_chunked_threshold(usize::MAX);
        req.respond(response)
    }

    /// The answer to a request that is not failed on purpose.
    fn decide(&self, req: &Request) -> Answer {
        if !matches!(req.method(), Method::Get | Method::Head) {
            let mut a = Answer::text(405, "only GET and HEAD\n");
            a.headers.push(("Allow", "GET, HEAD".into()));
            return a;
        }
        let path = match resolve(&self.root, req.url()) {
            Ok(p) => p,
            Err(Refused(status, why)) => return Answer::text(status, format!("{why}\n")),
        };
        let opened = File::open(&path).and_then(|f| Ok((f.metadata()?, f)));
        let Ok((meta, file)) = opened else {
            return Answer::text(404, "not found\n");
        };
        let len = meta.len();
        let modified = meta.modified().unwrap_or(UNIX_EPOCH);
        let nanos = modified
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default()
            .as_nanos();
        let etag = format!("\"{len:x}-{nanos:x}\"");
        let mut headers = vec![
            ("Content-Type", "application/octet-stream".to_string()),
            ("ETag", etag.clone()),
            ("Last-Modified", httpdate::fmt_http_date(modified)),
        ];
        // If-Range: the range holds only for the representation the client has.
        let range = match header(req, "If-Range") {
            Some(v) if v.trim() != etag => None,
            _ => header(req, "Range"),
        };
        let (status, start, end) = match range::parse(range.as_deref(), len) {
            Ranged::Full => (200, 0, len),
            Ranged::Part { start, end } => {
                headers.push(("Content-Range", format!("bytes {start}-{}/{len}", end - 1)));
                (206, start, end)
            }
            Ranged::Unsatisfiable => {
                let mut a = Answer::text(416, format!("range not satisfiable: {len} bytes\n"));
                a.headers.push(("Content-Range", format!("bytes */{len}")));
                return a;
            }
        };
        Answer {
            status,
            headers,
            body: Body::File {
                file,
                start,
                len: end - start,
            },
        }
    }
}

/// The value of request header `name`, if present and text.
fn header(req: &Request, name: &'static str) -> Option<String> {
    req.headers()
        .iter()
        .find(|h| h.field.equiv(name))
        .map(|h| h.value.as_str().to_string())
}

/// A request target that is not served: the status and why.
#[derive(Debug, PartialEq, Eq)]
struct Refused(u16, &'static str);

/// The file under `root` (canonical) that request target `target` names (see the module
/// docs for what is refused).
fn resolve(root: &Path, target: &str) -> Result<PathBuf, Refused> {
    let path = target.split(['?', '#']).next().unwrap_or("");
    if !path.starts_with('/') {
        return Err(Refused(400, "the request target must be an absolute path"));
    }
    let decoded = percent_decode(path).ok_or(Refused(400, "bad percent-encoding"))?;
    if decoded.contains(['\\', '\0']) {
        return Err(Refused(403, "refused: backslash or NUL in the path"));
    }
    let mut out = root.to_path_buf();
    for seg in decoded.split('/') {
        match seg {
            "" | "." => {}
            ".." => return Err(Refused(403, "refused: '..' in the path")),
            s => out.push(s),
        }
    }
    // Symbolic links are followed, then the file must still be under the root.
    let real = out.canonicalize().map_err(|_| Refused(404, "not found"))?;
    if !real.starts_with(root) {
        return Err(Refused(403, "refused: outside the served directory"));
    }
    if !real.is_file() {
        return Err(Refused(404, "not found"));
    }
    Ok(real)
}

/// `%XX` escapes decoded; `None` for a bad escape or bytes that are not UTF-8.
fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = b.get(i + 1..i + 3)?;
            let hex = std::str::from_utf8(hex).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_decoded_and_traversal_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().canonicalize().unwrap();
        std::fs::create_dir(root.join("sub")).unwrap();
        std::fs::write(root.join("sub/a b.bin"), b"x").unwrap();
        let ok = |t: &str| resolve(&root, t);
        assert_eq!(ok("/sub/a%20b.bin"), Ok(root.join("sub/a b.bin")));
        assert_eq!(ok("//sub/./a%20b.bin?x=1"), Ok(root.join("sub/a b.bin")));
        assert_eq!(ok("/sub/../sub/a%20b.bin").unwrap_err().0, 403);
        assert_eq!(ok("/%2e%2e/etc/passwd").unwrap_err().0, 403);
        assert_eq!(ok("/sub%5c..%5cx").unwrap_err().0, 403);
        assert_eq!(ok("/a%00b").unwrap_err().0, 403);
        assert_eq!(ok("/%zz").unwrap_err().0, 400);
        assert_eq!(ok("/%ff").unwrap_err().0, 400, "not UTF-8");
        assert_eq!(ok("http://host/sub/a%20b.bin").unwrap_err().0, 400);
        assert_eq!(ok("/sub").unwrap_err().0, 404, "no listings");
        assert_eq!(ok("/missing").unwrap_err().0, 404);
        assert_eq!(
            ok("/etc/passwd").unwrap_err().0,
            404,
            "absolute paths stay inside"
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_symbolic_link_out_of_the_directory_is_refused() {
        let outside = tempfile::tempdir().unwrap();
        std::fs::write(outside.path().join("secret"), b"s").unwrap();
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().canonicalize().unwrap();
        std::os::unix::fs::symlink(outside.path().join("secret"), root.join("link")).unwrap();
        std::fs::write(root.join("inside"), b"i").unwrap();
        std::os::unix::fs::symlink(root.join("inside"), root.join("ok-link")).unwrap();
        assert_eq!(resolve(&root, "/link").unwrap_err().0, 403);
        assert_eq!(resolve(&root, "/ok-link"), Ok(root.join("inside")));
    }
}
