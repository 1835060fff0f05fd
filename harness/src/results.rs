//! Results files: `frames.csv` (one row per frame, flushed as the run goes so partial results
//! survive a crash) and `summary.json` (written with `"complete": false` at the start and
//! rewritten with `true` at the end, so an interrupted run is never passed off as complete).
//!
//! Column order of `frames.csv` is part of the contract (units in the names); methods append
//! their own columns after [`FrameRow::COLUMNS`].

use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;

macro_rules! frame_row {
    ($( $(#[doc = $doc:literal])* $name:ident : $ty:ty ),* $(,)?) => {
        /// One frame of a run: the leading columns of `frames.csv`.
        #[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
        pub struct FrameRow {
            $( $(#[doc = $doc])* pub $name: $ty, )*
        }
        impl FrameRow {
            /// Column names, in file order.
            pub const COLUMNS: &'static [&'static str] = &[$(stringify!($name)),*];
            /// The row as CSV fields (`None` → empty field).
            pub fn fields(&self) -> Vec<String> {
                vec![$( Field::field(&self.$name) ),*]
            }
        }
    };
}

frame_row! {
    /// Frame index along the path.
    frame: u64,
    /// Method registry name.
    method: String,
    /// Scene label.
    scene: String,
    /// Camera path name.
    path: String,
    /// `eps` or `budget`.
    target: String,
    /// Pixel tolerance, for `eps` runs.
    eps_px: Option<f64>,
    /// Point budget, for `budget` runs.
    budget: Option<u64>,
    /// Splats drawn.
    points_drawn: u64,
    /// Cached chunks drawn.
    chunks_drawn: u64,
    /// GPU time of the render pass(es) (timestamp queries), ms; with occlusion culling the sum
    /// of the three phases' passes.
    gpu_ms: Option<f64>,
    /// Upload + encode + submit + wait, ms.
    wall_ms: f64,
    /// Time in the method's `frame` (selection), ms.
    cpu_select_ms: f64,
    /// Bytes uploaded this frame.
    upload_bytes: u64,
    /// points_drawn / (gpu_ms, else wall_ms).
    splats_per_s: f64,
    /// Resident set size after the frame.
    rss_bytes: u64,
    /// Bytes in the GPU chunk cache.
    gpu_cache_bytes: u64,
    /// PSNR against the reference, dB (capped at 100).
    psnr_db: Option<f64>,
    /// Mean SSIM against the reference.
    ssim: Option<f64>,
    /// Mean FLIP against the reference.
    flip_mean: Option<f64>,
    /// Reference-covered pixels left empty ÷ reference-covered pixels.
    hole_ratio: Option<f64>,
    /// Pixels covered only in this frame ÷ reference-covered pixels.
    extra_coverage: Option<f64>,
    /// FLIP(this frame, previous frame) − FLIP(reference, previous reference): popping
    /// ([`crate::metrics::PathMetrics`]); empty for frame 0 and runs without a reference.
    popping_flip: Option<f64>,
    /// Mean FLIP between this frame and the frame before it warped into its view by exact
    /// reprojection, over the valid pixels ([`crate::metrics::popping`]); empty for frame 0.
    warped_flip_l1: Option<f64>,
    /// The same for the reference's frames.
    warped_ref_flip_l1: Option<f64>,
    /// `warped_flip_l1 − warped_ref_flip_l1`: the popping the method adds, motion removed.
    popping_warped_l1: Option<f64>,
    /// Pop events at lag 1: valid pixels whose warped change exceeds the threshold where the
    /// reference's does not.
    pop_events_l1: Option<u64>,
    /// Fraction of pixels valid at lag 1 (covered, in view and not disoccluded).
    warp_valid_l1: Option<f64>,
    /// [`FrameRow::warped_flip_l1`] against the frame 7 before; empty for frames 0–6.
    warped_flip_l7: Option<f64>,
    /// [`FrameRow::warped_ref_flip_l1`] at lag 7.
    warped_ref_flip_l7: Option<f64>,
    /// [`FrameRow::popping_warped_l1`] at lag 7.
    popping_warped_l7: Option<f64>,
    /// [`FrameRow::pop_events_l1`] at lag 7.
    pop_events_l7: Option<u64>,
    /// [`FrameRow::warp_valid_l1`] at lag 7.
    warp_valid_l7: Option<f64>,
    /// Time to compute this frame's image metrics (both FLIP preparations, SSIM, PSNR,
    /// coverage and popping), ms; empty without a reference.
    metrics_ms: Option<f64>,
}

/// Formatting of one CSV field.
pub trait Field {
    /// The field's text.
    fn field(&self) -> String;
}
impl Field for u64 {
    fn field(&self) -> String {
        self.to_string()
    }
}
impl Field for f64 {
    fn field(&self) -> String {
        self.to_string()
    }
}
impl Field for String {
    fn field(&self) -> String {
        self.clone()
    }
}
impl<T: Field> Field for Option<T> {
    fn field(&self) -> String {
        self.as_ref().map(Field::field).unwrap_or_default()
    }
}

/// Appends rows to `frames.csv`, flushing each.
pub struct FramesWriter {
    path: PathBuf,
    w: csv::Writer<File>,
    extra: usize,
}

impl FramesWriter {
    /// Creates (truncates) `dir/frames.csv` with the header plus `extra` method columns.
    pub fn create(dir: &Path, extra: &[&str]) -> anyhow::Result<Self> {
        let path = dir.join("frames.csv");
        let file = File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        let mut w = csv::Writer::from_writer(file);
        let header: Vec<&str> = FrameRow::COLUMNS.iter().chain(extra).copied().collect();
        w.write_record(&header)
            .with_context(|| format!("writing {}", path.display()))?;
        w.flush()?;
        Ok(Self {
            path,
            w,
            extra: extra.len(),
        })
    }
    /// Appends a row and flushes it to disk.
    pub fn push(&mut self, row: &FrameRow, counters: &[f64]) -> anyhow::Result<()> {
        anyhow::ensure!(
            counters.len() == self.extra,
            "method returned {} counters for {} extra columns",
            counters.len(),
            self.extra
        );
        let mut rec = row.fields();
        rec.extend(counters.iter().map(|c| c.to_string()));
        self.w
            .write_record(&rec)
            .and_then(|_| self.w.flush().map_err(Into::into))
            .with_context(|| format!("writing {}", self.path.display()))
    }
}

/// Writes JSON atomically (temp file + rename).
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    let tmp = path.with_extension("json.tmp");
    let mut f = File::create(&tmp).with_context(|| format!("creating {}", tmp.display()))?;
    f.write_all(text.as_bytes())
        .and_then(|_| f.sync_all())
        .with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("renaming to {}", path.display()))
}

/// The command line of this process as a shell would take it back: `splatbench` and its
/// arguments, each quoted where it holds anything but `[A-Za-z0-9_./:=,@%+-]`. Results files
/// record it as the command that produced them.
pub fn invocation() -> String {
    std::iter::once("splatbench".to_string())
        .chain(std::env::args().skip(1).map(|a| shell_quote(&a)))
        .collect::<Vec<_>>()
        .join(" ")
}

/// `s` quoted for a POSIX shell where needed.
pub fn shell_quote(s: &str) -> String {
    let plain = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "_./:=,@%+-".contains(c));
    if plain {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// Reads a JSON file into `T`; errors name the file.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> anyhow::Result<T> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))
}

/// The `summary.json` of the run in `dir`, as JSON; a run that did not finish
/// (`"complete": false`) is an error naming the file: its figures are not a measurement.
pub fn read_complete_summary(dir: &Path) -> anyhow::Result<serde_json::Value> {
    let path = dir.join("summary.json");
    let v: serde_json::Value = read_json(&path)?;
    if v["complete"] != true {
        anyhow::bail!("{}: the run did not complete", path.display());
    }
    Ok(v)
}

/// The parts of an experiment that emitted jobs wrote, checked for a merge: `parts` holds
/// each directory with the part numbers it ran and whether it finished; `n` parts exist,
/// `name(k)` says which part `k` is in messages. Returns the directory of each part in
/// order. An unfinished part, a part number out of range, a part given twice and a part
/// missing are errors naming the directories and parts.
pub fn cover<'a>(
    parts: &[(&'a PathBuf, Vec<usize>, bool)],
    n: usize,
    name: impl Fn(usize) -> String,
) -> anyhow::Result<Vec<&'a PathBuf>> {
    let mut seen: Vec<Option<&'a PathBuf>> = vec![None; n];
    for (d, ks, complete) in parts {
        if !complete {
            anyhow::bail!(
                "{}: this part did not finish (its record says \"complete\": false)",
                d.display()
            );
        }
        for &k in ks {
            match seen.get_mut(k) {
                None => anyhow::bail!("{}: part {k} of {n} parts", d.display()),
                Some(Some(other)) => anyhow::bail!(
                    "part {k} ({}) is in both {} and {}",
                    name(k),
                    other.display(),
                    d.display()
                ),
                Some(slot) => *slot = Some(*d),
            }
        }
    }
    let missing: Vec<String> = (0..n).filter(|&k| seen[k].is_none()).map(&name).collect();
    if !missing.is_empty() {
        anyhow::bail!(
            "merge: part(s) {} missing (did their jobs run?)",
            missing.join(", ")
        );
    }
    Ok(seen.into_iter().flatten().collect())
}

/// Puts the tree `from` at `to` (directories created, files hard-linked where the file
/// system allows, else copied; symbolic links are not followed and are an error). A file
/// that exists at `to` already is an error naming it: trees merged this way must not
/// overlap.
pub fn link_tree(from: &Path, to: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(to).with_context(|| format!("creating {}", to.display()))?;
    for e in std::fs::read_dir(from).with_context(|| format!("reading {}", from.display()))? {
        let e = e.with_context(|| format!("reading {}", from.display()))?;
        let (src, dst) = (e.path(), to.join(e.file_name()));
        let t = e
            .file_type()
            .with_context(|| format!("reading {}", src.display()))?;
        if t.is_dir() {
            link_tree(&src, &dst)?;
        } else if t.is_file() {
            if dst.exists() {
                anyhow::bail!(
                    "{} and {} would both be {}",
                    src.display(),
                    dst.display(),
                    dst.display()
                );
            }
            if std::fs::hard_link(&src, &dst).is_err() {
                std::fs::copy(&src, &dst)
                    .with_context(|| format!("copying {} to {}", src.display(), dst.display()))?;
            }
        } else {
            anyhow::bail!("{}: not a file or directory", src.display());
        }
    }
    Ok(())
}

/// Median of the finite values, if any.
pub fn median(values: impl IntoIterator<Item = f64>) -> Option<f64> {
    let mut v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    Some(if v.len() % 2 == 1 {
        v[m]
    } else {
        (v[m - 1] + v[m]) / 2.0
    })
}

/// The `q`-quantile (0..=1) of the finite `values` by linear interpolation between order
/// statistics (position `q · (n − 1)`, as numpy's default), `None` if there is none;
/// [`median`] is the 0.5-quantile.
pub fn quantile(values: impl IntoIterator<Item = f64>, q: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let at = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (lo, hi) = (at.floor() as usize, at.ceil() as usize);
    Some(v[lo] + (v[hi] - v[lo]) * (at - lo as f64))
}

/// Files and bytes under `dir` (0 for a folder that does not exist). Symbolic links are
/// counted as links, never followed.
pub fn dir_size(dir: &std::path::Path) -> std::io::Result<(u64, u64)> {
    let mut total = (0, 0);
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(total),
        Err(e) => return Err(e),
    };
    for e in entries {
        let e = e?;
        let t = e.file_type()?;
        if t.is_dir() {
            let (f, b) = dir_size(&e.path())?;
            total = (total.0 + f, total.1 + b);
        } else {
            total = (total.0 + 1, total.1 + e.metadata()?.len());
        }
    }
    Ok(total)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_are_the_contract() {
        assert_eq!(
            FrameRow::COLUMNS.join(","),
            "frame,method,scene,path,target,eps_px,budget,points_drawn,chunks_drawn,gpu_ms,\
             wall_ms,cpu_select_ms,upload_bytes,splats_per_s,rss_bytes,gpu_cache_bytes,psnr_db,\
             ssim,flip_mean,hole_ratio,extra_coverage,popping_flip,warped_flip_l1,\
             warped_ref_flip_l1,popping_warped_l1,pop_events_l1,warp_valid_l1,warped_flip_l7,\
             warped_ref_flip_l7,popping_warped_l7,pop_events_l7,warp_valid_l7,metrics_ms"
        );
    }

    #[test]
    fn shell_quoting() {
        assert_eq!(shell_quote("statue:20000:1"), "statue:20000:1");
        assert_eq!(shell_quote("a b"), "'a b'");
        assert_eq!(shell_quote("it's"), "'it'\\''s'");
        assert_eq!(shell_quote(""), "''");
    }

    #[test]
    fn quantiles() {
        let v = [4.0, 1.0, 3.0, 2.0, 5.0];
        assert_eq!(quantile(v, 0.5), median(v));
        assert_eq!(quantile(v, 0.95), Some(4.8));
        assert_eq!(quantile(v, 1.0), Some(5.0));
        assert_eq!(quantile([7.0], 0.95), Some(7.0));
        assert_eq!(quantile([f64::NAN], 0.95), None);
    }

    #[test]
    fn medians() {
        assert_eq!(median([3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median([4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median([f64::NAN]), None);
    }
}
