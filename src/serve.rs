//! `splatbench serve`: a build directory over HTTP/1.1 with byte ranges ([`harness::serve`]),
//! for remote runs and for experiments on a throttled, slow or failing link. Prints
//! `serving DIR at http://ADDR/` on standard output once it listens (with `--addr
//! 127.0.0.1:0` the port is the free one it took), then the access log on standard error (or
//! `--log FILE`), until interrupted.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context as _, bail};
use clap::Args;
use harness::serve::{ServeOptions, Server};

#[derive(Args)]
pub struct ServeArgs {
    /// The directory served (a build directory, or a folder of them).
    pub dir: PathBuf,
    /// Address to listen on (port 0: any free port, printed).
    #[arg(long, default_value = "127.0.0.1:8000")]
    pub addr: SocketAddr,
    /// Throttle every response body to this many MB/s (10⁶ bytes), shared by all
    /// connections as one link.
    #[arg(long, value_name = "MB/s")]
    pub bandwidth: Option<f64>,
    /// Milliseconds added before each response.
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub latency: u64,
    /// Answer every request after the first N with 500 Internal Server Error.
    #[arg(long, value_name = "N")]
    pub fail_after: Option<u64>,
    /// Requests answered at once (a throttled body holds one for its whole transfer).
    #[arg(long, default_value_t = 8)]
    pub threads: usize,
    /// Append the access log to this file instead of standard error.
    #[arg(long)]
    pub log: Option<PathBuf>,
}

/// `splatbench serve`.
pub fn main(a: &ServeArgs) -> anyhow::Result<()> {
    let bandwidth = match a.bandwidth {
        Some(b) if !(b.is_finite() && b > 0.0) => {
            bail!("--bandwidth {b}: must be a positive number of MB/s")
        }
        b => b.map(|b| b * 1e6),
    };
    if a.threads == 0 {
        bail!("--threads 0: at least one thread must answer requests");
    }
    let log: harness::serve::Log = match &a.log {
        Some(p) => Box::new(
            std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(p)
                .with_context(|| format!("--log {}", p.display()))?,
        ),
        None => Box::new(std::io::stderr()),
    };
    let opt = ServeOptions {
        root: a.dir.clone(),
        addr: a.addr,
        bandwidth,
        latency: Duration::from_millis(a.latency),
        fail_after: a.fail_after,
        threads: a.threads,
        clock: Default::default(),
    };
    let server = Server::start(&opt, log)?;
    println!("serving {} at {}", a.dir.display(), server.url());
    use std::io::Write as _;
    std::io::stdout().flush()?;
    // Serves until the process is interrupted; the workers never return on their own.
    loop {
        std::thread::park();
    }
}
