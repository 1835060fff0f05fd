//! Helpers shared by the tests of `harness::serve` and of the clients that read from it
//! (`serve.rs`, `remote_source.rs`).
#![allow(dead_code, clippy::unwrap_used)]

use std::io::Write;
use std::path::Path;
use std::sync::{Arc, Mutex};

use harness::serve::{ServeOptions, Server};

/// An access log the tests can read while the server writes it.
#[derive(Clone, Default)]
pub struct SharedLog(Arc<Mutex<Vec<u8>>>);

impl SharedLog {
    /// What has been logged so far.
    pub fn text(&self) -> String {
        String::from_utf8(self.0.lock().unwrap().clone()).unwrap()
    }
}

impl Write for SharedLog {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// A server of `root` on an ephemeral loopback port, its options changed by `f`, logging to
/// the returned log.
pub fn serve(root: &Path, f: impl FnOnce(&mut ServeOptions)) -> (Server, SharedLog) {
    let mut opt = ServeOptions::new(root, "127.0.0.1:0".parse().unwrap());
    f(&mut opt);
    let log = SharedLog::default();
    (Server::start(&opt, Box::new(log.clone())).unwrap(), log)
}
