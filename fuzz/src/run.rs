//! Running a target: the iterations run in a child process (this binary re-executed with
//! [`CHILD_ENV`] set) under an address-space limit, so an abort, an out-of-memory or a hang
//! kills only the child. The parent reads one line per iteration from the child's stdout,
//! knows which iteration was running when the child died or stopped answering, makes that
//! input again from `(seed, iteration)` and saves it as a reproducer, then restarts the
//! child after it. A panic is caught in the child (`catch_unwind`, and a panic hook for
//! threads a decoder spawns) and reported on the same channel.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crate::corpus::{Corpus, Input};
use crate::targets::Target;
use crate::{execute, inputs, seeds};

/// Set in the child's environment; its value is ignored.
pub const CHILD_ENV: &str = "SPLATBENCH_FUZZ_CHILD";
/// When set, the child prints every decoder error on stderr (run the child directly to see
/// them: `SPLATBENCH_FUZZ_CHILD=1 SPLATBENCH_FUZZ_ERRORS=1 fuzz TARGET --iters N`).
pub const ERRORS_ENV: &str = "SPLATBENCH_FUZZ_ERRORS";

/// How a run is set up.
#[derive(Debug, Clone)]
pub struct Options {
    /// Iterations (inputs) per target.
    pub iters: u64,
    /// The random stream: input `i` depends on `(seed, i)` only.
    pub seed: u64,
    /// Longest an iteration may take before it counts as a hang.
    pub timeout: Duration,
    /// The child's address-space limit in MiB (`RLIMIT_AS`; 0 = none).
    pub mem_mb: u64,
    /// Where reproducers are written.
    pub crashes: PathBuf,
}

/// What kind of finding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A panic (caught in the child).
    Panic,
    /// The child died: a signal (abort, segfault, out of memory) or an unexpected exit.
    Crash,
    /// An iteration ran past the timeout.
    Hang,
}

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Kind::Panic => "panic",
            Kind::Crash => "crash",
            Kind::Hang => "hang",
        })
    }
}

/// One distinct finding (same kind and place), with how often it was hit.
#[derive(Debug, Clone)]
pub struct Finding {
    /// Its kind.
    pub kind: Kind,
    /// The first iteration that hit it.
    pub iteration: u64,
    /// The panic message and location, or how the child died.
    pub message: String,
    /// Inputs that hit it.
    pub hits: u64,
    /// The saved input of the first hit.
    pub reproducer: Option<PathBuf>,
}

/// The result of one target's run.
#[derive(Debug, Clone)]
pub struct Report {
    /// The target.
    pub target: Target,
    /// Inputs executed (including those that crashed or hung).
    pub execs: u64,
    /// Inputs the decoder accepted (no error): how far mutations get past the checks.
    pub accepted: u64,
    /// Wall time, seconds (child start-up and seed building included).
    pub seconds: f64,
    /// Child processes started.
    pub children: u64,
    /// Distinct findings.
    pub findings: Vec<Finding>,
}

// ---------------------------------------------------------------------------------------------
// The child
// ---------------------------------------------------------------------------------------------

/// The first panic of the current iteration that is a finding whether or not it is caught:
/// on another thread than the one running the iterations (a loader thread), or in this
/// workspace's own code: message and location.
static THREAD_PANIC: Mutex<Option<String>> = Mutex::new(None);
/// The last panic in a dependency's code on the iterating thread. It is a finding only when
/// it escapes the decoder (`catch_unwind` sees it): a reader may contain a third-party
/// crate's panic and return an error, which is the behaviour wanted.
static MAIN_PANIC: Mutex<Option<String>> = Mutex::new(None);
static MAIN_THREAD: std::sync::OnceLock<std::thread::ThreadId> = std::sync::OnceLock::new();

#[cfg(unix)]
#[expect(
    unsafe_code,
    reason = "setrlimit is a libc call on a plain struct; lowering the limit of this process \
              cannot violate memory safety"
)]
fn limit_memory(mb: u64) {
    if mb == 0 {
        return;
    }
    let bytes = mb.saturating_mul(1 << 20) as libc::rlim_t;
    let lim = libc::rlimit {
        rlim_cur: bytes,
        rlim_max: bytes,
    };
    // SAFETY: see `reason`; failure leaves the process unlimited, which only loses the
    // out-of-memory detection.
    if unsafe { libc::setrlimit(libc::RLIMIT_AS, &lim) } != 0 {
        eprintln!("fuzz: setrlimit(RLIMIT_AS) failed; running without a memory limit");
    }
}

#[cfg(not(unix))]
fn limit_memory(_mb: u64) {}

fn one_line(s: &str) -> String {
    s.replace(['\n', '\r'], " ")
}

/// The child's loop: iterations `start..opts.iters` of `target`, one line each on stdout
/// (`R` when the seeds are ready, `S i` before an input, `O` after one the decoder accepted,
/// `P i message` after a panic, `D` at the end).
pub fn child(target: Target, opts: &Options, start: u64) -> Result<(), String> {
    limit_memory(opts.mem_mb);
    std::panic::set_hook(Box::new(|info| {
        let msg = scenes::error::panic_message(info.payload())
            .unwrap_or_else(|| "(non-string panic)".into());
        let at = info
            .location()
            .map_or_else(String::new, |l| format!(" at {}:{}", l.file(), l.line()));
        let main = MAIN_THREAD.get() == Some(&std::thread::current().id());
        // A panic in this workspace's code is a bug even when a reader contains it (as the
        // LAS reader contains the laz crate's): only third-party panics may be contained.
        let ours = info.location().is_some_and(|l| {
            !l.file().contains("/.cargo/registry/") && !l.file().starts_with("/rustc/")
        });
        if main && !ours {
            if let Ok(mut slot) = MAIN_PANIC.lock() {
                *slot = Some(format!("{msg}{at}"));
            }
        } else if let Ok(mut slot) = THREAD_PANIC.lock() {
            slot.get_or_insert(format!(
                "{msg}{at} (in thread {:?})",
                std::thread::current().name()
            ));
        }
    }));
    let _ = MAIN_THREAD.set(std::thread::current().id());
    let work = scratch_dir("child");
    let corpus = seeds::corpus(target, &work.join("seeds"))?;
    let mut out = std::io::stdout().lock();
    let mut say = |line: String| {
        let _ = out.write_all(line.as_bytes());
        let _ = out.flush();
    };
    say("R\n".into());
    let scratch = work.join("run");
    let show_errors = std::env::var_os(ERRORS_ENV).is_some();
    for i in start..opts.iters {
        say(format!("S {i}\n"));
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let input = inputs::input(target, &corpus, opts.seed, i);
            execute::execute(target, &corpus, &input, &scratch)
        }));
        let main = MAIN_PANIC.lock().ok().and_then(|mut s| s.take());
        let thread = THREAD_PANIC.lock().ok().and_then(|mut s| s.take());
        match &caught {
            Ok(Ok(())) => say("O\n".into()),
            Ok(Err(e)) if show_errors => eprintln!("input {i}: {}", one_line(e)),
            _ => {}
        }
        let finding = if caught.is_err() {
            Some(main.or(thread).unwrap_or_else(|| "a panic".into()))
        } else {
            thread
        };
        if let Some(msg) = finding {
            say(format!("P {i} {}\n", one_line(&msg)));
        }
    }
    say("D\n".into());
    let _ = std::fs::remove_dir_all(&work);
    Ok(())
}

fn scratch_dir(what: &str) -> PathBuf {
    std::env::temp_dir().join(format!("splatbench-fuzz-{what}-{}", std::process::id()))
}

// ---------------------------------------------------------------------------------------------
// The parent
// ---------------------------------------------------------------------------------------------

enum Msg {
    Ready,
    Accepted,
    Start(u64),
    Panic(u64, String),
    Done,
}

fn parse(line: &str) -> Option<Msg> {
    let mut parts = line.splitn(3, ' ');
    match parts.next()? {
        "R" => Some(Msg::Ready),
        "O" => Some(Msg::Accepted),
        "D" => Some(Msg::Done),
        "S" => parts.next()?.parse().ok().map(Msg::Start),
        "P" => {
            let i = parts.next()?.parse().ok()?;
            Some(Msg::Panic(i, parts.next().unwrap_or("").to_owned()))
        }
        _ => None,
    }
}

#[cfg(unix)]
fn death(status: std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match status.signal() {
        Some(s) => {
            let name = match s {
                libc::SIGABRT => "SIGABRT",
                libc::SIGSEGV => "SIGSEGV",
                libc::SIGBUS => "SIGBUS",
                libc::SIGKILL => "SIGKILL",
                libc::SIGILL => "SIGILL",
                libc::SIGFPE => "SIGFPE",
                _ => "signal",
            };
            format!("killed by signal {s} ({name})")
        }
        None => format!("exited with {status}"),
    }
}

#[cfg(not(unix))]
fn death(status: std::process::ExitStatus) -> String {
    format!("exited with {status}")
}

/// A place-independent key for grouping findings: the message without numbers (sizes,
/// indices and addresses differ between inputs that hit the same bug).
fn key(kind: Kind, msg: &str) -> String {
    let digitless: String = msg.chars().filter(|c| !c.is_ascii_digit()).collect();
    // A panic's location has digits that matter: keep them.
    let at = msg.rsplit(" at ").next().filter(|_| kind == Kind::Panic);
    format!("{kind}|{digitless}|{}", at.unwrap_or(""))
}

struct Saver<'a> {
    target: Target,
    opts: &'a Options,
    corpus: Option<Corpus>,
}

impl Saver<'_> {
    /// Makes input `i` again and writes it (and a note of what it is) under `crashes/`.
    fn save(&mut self, f: &Finding) -> Result<PathBuf, String> {
        if self.corpus.is_none() {
            let work = scratch_dir("parent").join("seeds");
            self.corpus = Some(seeds::corpus(self.target, &work)?);
        }
        let corpus = self.corpus.as_ref().ok_or("no corpus")?;
        // The child already reported a panic of the input generator itself; here it would
        // stop the whole run.
        let input = std::panic::catch_unwind(|| {
            inputs::input(self.target, corpus, self.opts.seed, f.iteration)
        })
        .map_err(|_| format!("input {} could not be made again", f.iteration))?;
        let hash = scenes::hash::fnv1a64(&input.bytes);
        std::fs::create_dir_all(&self.opts.crashes)
            .map_err(|e| format!("{}: {e}", self.opts.crashes.display()))?;
        let name = format!("{}-{hash:016x}", self.target.name());
        let bin = self.opts.crashes.join(format!("{name}.bin"));
        std::fs::write(&bin, &input.bytes).map_err(|e| format!("{}: {e}", bin.display()))?;
        let note = format!(
            "target = \"{}\"\nseed_file = \"{}\"\nseed = {}\niteration = {}\nkind = \"{}\"\n\
             message = {:?}\n",
            self.target.name(),
            corpus.seeds[input.seed].name,
            self.opts.seed,
            f.iteration,
            f.kind,
            f.message
        );
        let txt = self.opts.crashes.join(format!("{name}.txt"));
        std::fs::write(&txt, note).map_err(|e| format!("{}: {e}", txt.display()))?;
        Ok(bin)
    }
}

/// Runs `target` for `opts.iters` inputs under supervision (see the module docs).
pub fn supervise(target: Target, opts: &Options) -> Result<Report, String> {
    let t0 = Instant::now();
    let exe = std::env::current_exe().map_err(|e| format!("current executable: {e}"))?;
    let mut findings: Vec<(String, Finding)> = Vec::new();
    let mut saver = Saver {
        target,
        opts,
        corpus: None,
    };
    let mut record = |kind: Kind, i: u64, msg: String, saver: &mut Saver| -> Result<(), String> {
        let k = key(kind, &msg);
        if let Some((_, f)) = findings.iter_mut().find(|(fk, _)| *fk == k) {
            f.hits += 1;
            return Ok(());
        }
        let mut f = Finding {
            kind,
            iteration: i,
            message: msg,
            hits: 1,
            reproducer: None,
        };
        f.reproducer = match saver.save(&f) {
            Ok(p) => Some(p),
            Err(e) => {
                eprintln!("fuzz: no reproducer for iteration {i}: {e}");
                None
            }
        };
        findings.push((k, f));
        Ok(())
    };
    let mut next = 0u64;
    let mut execs = 0u64;
    let mut accepted = 0u64;
    let mut children = 0u64;
    while next < opts.iters {
        children += 1;
        let mut child = Command::new(&exe)
            .arg(target.name())
            .args(["--iters", &opts.iters.to_string()])
            .args(["--seed", &opts.seed.to_string()])
            .args(["--mem-mb", &opts.mem_mb.to_string()])
            .args(["--start", &next.to_string()])
            .env(CHILD_ENV, "1")
            .env("MALLOC_ARENA_MAX", "2")
            .env("RUST_BACKTRACE", "0")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| format!("starting {}: {e}", exe.display()))?;
        let (tx, rx) = mpsc::channel();
        let stdout = child.stdout.take().ok_or("no child stdout")?;
        let reader = std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if let Some(m) = parse(&line)
                    && tx.send(m).is_err()
                {
                    break;
                }
            }
        });
        let mut stderr = child.stderr.take().ok_or("no child stderr")?;
        let errs = std::thread::spawn(move || {
            let mut all = Vec::new();
            let _ = stderr.read_to_end(&mut all);
            let text = String::from_utf8_lossy(&all).into_owned();
            let tail: Vec<&str> = text.lines().rev().take(3).collect();
            tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
        });
        let mut current: Option<u64> = None;
        let mut done = false;
        let mut hung = false;
        let mut ready = false;
        loop {
            // Building the seeds (method builds) may take longer than one iteration.
            let wait = if ready {
                opts.timeout
            } else {
                opts.timeout.max(Duration::from_secs(300))
            };
            match rx.recv_timeout(wait) {
                Ok(Msg::Ready) => ready = true,
                Ok(Msg::Accepted) => accepted += 1,
                Ok(Msg::Start(i)) => {
                    current = Some(i);
                    execs += 1;
                }
                Ok(Msg::Panic(i, msg)) => record(Kind::Panic, i, msg, &mut saver)?,
                Ok(Msg::Done) => done = true,
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    hung = true;
                    let _ = child.kill();
                    break;
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
        }
        let status = child
            .wait()
            .map_err(|e| format!("waiting for the child: {e}"))?;
        let _ = reader.join();
        let stderr = errs.join().unwrap_or_default();
        if done {
            next = opts.iters;
            continue;
        }
        let Some(i) = current else {
            return Err(format!(
                "{}: the child failed before its first input ({}): {stderr}",
                target.name(),
                death(status)
            ));
        };
        if hung {
            let msg = format!("no answer within {:?}", opts.timeout);
            record(Kind::Hang, i, msg, &mut saver)?;
        } else {
            let msg = format!("{}: {stderr}", death(status));
            record(Kind::Crash, i, msg, &mut saver)?;
        }
        next = i + 1;
    }
    Ok(Report {
        target,
        execs,
        accepted,
        seconds: t0.elapsed().as_secs_f64(),
        children,
        findings: findings.into_iter().map(|(_, f)| f).collect(),
    })
}

/// Runs one saved input in this process (no child), for debugging a reproducer: the seed
/// file it replaces is read from the `.txt` note beside it when there is one.
pub fn replay(target: Target, file: &Path) -> Result<Result<(), String>, String> {
    let bytes = std::fs::read(file).map_err(|e| format!("{}: {e}", file.display()))?;
    let note = std::fs::read_to_string(file.with_extension("txt")).unwrap_or_default();
    let seed_name = note
        .lines()
        .find_map(|l| l.strip_prefix("seed_file = "))
        .map(|s| s.trim_matches('"').to_owned());
    let work = scratch_dir("replay");
    let corpus = seeds::corpus(target, &work.join("seeds"))?;
    let seed = seed_name
        .and_then(|n| corpus.seeds.iter().position(|s| s.name == n))
        .unwrap_or(0);
    let input = Input { seed, bytes };
    let out = execute::execute(target, &corpus, &input, &work.join("run"));
    let _ = std::fs::remove_dir_all(&work);
    Ok(out)
}
