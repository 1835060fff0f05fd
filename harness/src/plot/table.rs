//! Reading the CSV tables the plots are drawn from: `frames.csv` and `sweep.csv`, by column
//! name, with errors naming the file, column and row.

use super::*;

/// Columns added after files were committed with the older header: a file without them
/// reads as if they were empty in every row.
pub(super) const OPTIONAL_COLUMNS: [&str; 8] = [
    "popping_flip",
    "popping_flip_median",
    "popping_warped_l1",
    "popping_warped_l7",
    "popping_warped_l1_median",
    "popping_warped_l1_p95",
    "popping_warped_l7_median",
    "popping_warped_l7_p95",
];

/// Reads a CSV file whose header holds `columns` (any order, extra columns ignored; those of
/// [`OPTIONAL_COLUMNS`] may be missing), one `parse` per record. Errors name the file; a file without rows is an error ("no `what` in
/// file").
pub(super) fn read_table<T>(
    csv_path: &Path,
    columns: &[&str],
    what: &str,
    parse: impl Fn(&Row<'_>) -> anyhow::Result<T>,
) -> anyhow::Result<Vec<T>> {
    let file = csv_path.display();
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(csv_path)
        .with_context(|| format!("cannot open {file}"))?;
    let headers = reader
        .headers()
        .with_context(|| format!("cannot read the header of {file}"))?;
    if headers.iter().all(str::is_empty) {
        bail!("no {what} in {file} (the file is empty)");
    }
    let index = columns
        .iter()
        .map(|&column| match headers.iter().position(|h| h == column) {
            Some(i) => Ok(Some(i)),
            None if OPTIONAL_COLUMNS.contains(&column) => Ok(None),
            None => Err(anyhow!("{file}: missing column '{column}'")),
        })
        .collect::<anyhow::Result<Vec<Option<usize>>>>()?;
    let mut rows = Vec::new();
    for (n, record) in reader.records().enumerate() {
        let record = record.with_context(|| format!("cannot read {file}"))?;
        let row = Row {
            file: csv_path,
            row: n + 1,
            record: &record,
            columns,
            index: &index,
        };
        rows.push(parse(&row)?);
    }
    if rows.is_empty() {
        bail!("no {what} in {file}");
    }
    Ok(rows)
}

/// One CSV record being parsed, with what error messages need.
pub(super) struct Row<'a> {
    /// The CSV file.
    pub(super) file: &'a Path,
    /// 1-based data row.
    pub(super) row: usize,
    /// The record.
    pub(super) record: &'a csv::StringRecord,
    /// The columns read (e.g. [`FRAME_COLUMNS`]).
    pub(super) columns: &'a [&'a str],
    /// Position in the record of each of `columns` (`None`: an optional column missing).
    pub(super) index: &'a [Option<usize>],
}

impl Row<'_> {
    /// The trimmed text of column `name` (one of `columns`).
    fn text(&self, name: &str) -> &str {
        self.columns
            .iter()
            .position(|&c| c == name)
            .and_then(|c| self.record.get(self.index[c]?))
            .unwrap_or("")
    }

    /// An error about column `name` of this row.
    fn error(&self, name: &str, what: &str) -> anyhow::Error {
        let line = self
            .record
            .position()
            .map_or(String::new(), |p| format!(" (line {})", p.line()));
        anyhow!(
            "{}: row {}{line}, column '{name}': {what}",
            self.file.display(),
            self.row,
        )
    }

    /// Column `name` as text, which must not be empty.
    fn string(&self, name: &str) -> anyhow::Result<String> {
        match self.text(name) {
            "" => Err(self.error(name, "empty")),
            s => Ok(s.to_owned()),
        }
    }

    /// Column `name` as a finite number, or `None` when empty.
    fn opt_f64(&self, name: &str) -> anyhow::Result<Option<f64>> {
        let s = self.text(name);
        if s.is_empty() {
            return Ok(None);
        }
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            _ => Err(self.error(name, &format!("\"{s}\" is not a finite number"))),
        }
    }

    /// Column `name` as an unsigned integer, or `None` when empty.
    fn opt_u64(&self, name: &str) -> anyhow::Result<Option<u64>> {
        let s = self.text(name);
        if s.is_empty() {
            return Ok(None);
        }
        s.parse::<u64>()
            .map(Some)
            .map_err(|_| self.error(name, &format!("\"{s}\" is not an unsigned integer")))
    }

    /// Column `name` as a finite number; empty is an error.
    fn f64(&self, name: &str) -> anyhow::Result<f64> {
        self.opt_f64(name)?
            .ok_or_else(|| self.error(name, "empty, a number is required"))
    }

    /// Column `name` as an unsigned integer; empty is an error.
    fn u64(&self, name: &str) -> anyhow::Result<u64> {
        self.opt_u64(name)?
            .ok_or_else(|| self.error(name, "empty, an integer is required"))
    }

    /// Column `target`: `eps` or `budget`.
    fn target(&self) -> anyhow::Result<String> {
        let target = self.string("target")?;
        if target != "eps" && target != "budget" {
            return Err(self.error(
                "target",
                &format!("\"{target}\" is neither \"eps\" nor \"budget\""),
            ));
        }
        Ok(target)
    }

    /// The whole record, as a frame of `frames.csv`.
    pub(super) fn parse(&self) -> anyhow::Result<FrameRecord> {
        let target = self.target()?;
        Ok(FrameRecord {
            frame: self.u64("frame")?,
            method: self.string("method")?,
            scene: self.string("scene")?,
            path: self.string("path")?,
            target,
            eps_px: self.opt_f64("eps_px")?,
            budget: self.opt_u64("budget")?,
            points_drawn: self.u64("points_drawn")?,
            chunks_drawn: self.u64("chunks_drawn")?,
            gpu_ms: self.opt_f64("gpu_ms")?,
            wall_ms: self.f64("wall_ms")?,
            cpu_select_ms: self.f64("cpu_select_ms")?,
            upload_bytes: self.u64("upload_bytes")?,
            splats_per_s: self.f64("splats_per_s")?,
            rss_bytes: self.u64("rss_bytes")?,
            gpu_cache_bytes: self.u64("gpu_cache_bytes")?,
            psnr_db: self.opt_f64("psnr_db")?,
            ssim: self.opt_f64("ssim")?,
            flip_mean: self.opt_f64("flip_mean")?,
            hole_ratio: self.opt_f64("hole_ratio")?,
            extra_coverage: self.opt_f64("extra_coverage")?,
            popping_flip: self.opt_f64("popping_flip")?,
            popping_warped_l1: self.opt_f64("popping_warped_l1")?,
            popping_warped_l7: self.opt_f64("popping_warped_l7")?,
        })
    }

    /// The whole record, as a row of `sweep.csv`.
    pub(super) fn parse_sweep(&self) -> anyhow::Result<SweepRow> {
        Ok(SweepRow {
            method: self.string("method")?,
            params: self.text("params").to_owned(),
            scene: self.string("scene")?,
            path: self.string("path")?,
            target: self.target()?,
            value: self.f64("value")?,
            frames: self.u64("frames")?,
            points_drawn_median: self.f64("points_drawn_median")?,
            splats_per_s_median: self.f64("splats_per_s_median")?,
            gpu_ms_median: self.opt_f64("gpu_ms_median")?,
            cpu_select_ms_median: self.f64("cpu_select_ms_median")?,
            flip_mean_median: self.opt_f64("flip_mean_median")?,
            flip_mean_max: self.opt_f64("flip_mean_max")?,
            hole_ratio_median: self.opt_f64("hole_ratio_median")?,
            hole_ratio_max: self.opt_f64("hole_ratio_max")?,
            psnr_db_median: self.opt_f64("psnr_db_median")?,
            popping_flip_median: self.opt_f64("popping_flip_median")?,
            popping_warped_l1_median: self.opt_f64("popping_warped_l1_median")?,
            popping_warped_l1_p95: self.opt_f64("popping_warped_l1_p95")?,
            popping_warped_l7_median: self.opt_f64("popping_warped_l7_median")?,
            popping_warped_l7_p95: self.opt_f64("popping_warped_l7_p95")?,
            rss_bytes_max: self.u64("rss_bytes_max")?,
        })
    }
}
