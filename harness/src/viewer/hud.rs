//! The on-screen HUD: what the frame cost and what the viewer is doing, as lines of text
//! ([`lines`], a plain function) drawn with the plots' bundled font into an image
//! ([`draw`]) that the window shows in a band above the frame ([`super::present::frame_rect`]).

use methods::{MethodKind, Target};
use plotters::prelude::*;

use super::control::Mode;
use crate::image::Image;
use crate::render::{FrameStats, RenderSettings};

/// Which image the window shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Overlay {
    /// The method's frame (the renderer's target).
    #[default]
    Method,
    /// The full-resolution reference.
    Reference,
    /// FLIP heat map of the frame against the reference.
    Flip,
    /// The frame with the reference's splats it misses in red.
    Holes,
}

impl Overlay {
    /// The name the HUD shows.
    pub fn name(self) -> &'static str {
        match self {
            Overlay::Method => "method",
            Overlay::Reference => "reference",
            Overlay::Flip => "FLIP map",
            Overlay::Holes => "holes",
        }
    }
}

/// What the last frame cost and found, for the HUD.
#[derive(Debug, Clone, Default)]
pub struct FrameInfo {
    /// The renderer's statistics.
    pub stats: FrameStats,
    /// Time the method took to select the draw list, ms.
    pub cpu_select_ms: f64,
    /// The whole frame (select + draw + overlays), ms.
    pub frame_ms: f64,
    /// FLIP of the frame measured on request (`C`), with the frame number.
    pub flip: Option<(u64, f64)>,
    /// Chunks that failed to load so far.
    pub failed_chunks: usize,
    /// The loader's requests issued / failed and bytes read so far (methods that load).
    pub traffic: Option<methods::store::access::Traffic>,
}

/// What the HUD reports.
pub struct HudState<'a> {
    /// The methods (keys 1…9).
    pub methods: Vec<MethodKind>,
    /// The one shown.
    pub current: usize,
    /// Tolerance or budget.
    pub target: Target,
    /// Renderer settings (kernel, raster, size).
    pub settings: RenderSettings,
    /// The last frame.
    pub info: &'a FrameInfo,
    /// The image shown.
    pub overlay: Overlay,
    /// Chunks coloured by level.
    pub levels: bool,
    /// Fly or orbit.
    pub mode: Mode,
    /// Fly speed, scene radii per second.
    pub speed: f64,
    /// Keyframes recorded.
    pub keyframes: usize,
    /// (frame, of frames) of a path playing.
    pub playing: Option<(usize, usize)>,
    /// The last message.
    pub message: &'a str,
    /// Whether the adapter has timestamp queries (else GPU time is unknown).
    pub timestamps: bool,
}

fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / f64::from(1u32 << 20))
}

/// The HUD's lines.
pub fn lines(s: &HudState<'_>) -> Vec<String> {
    let i = s.info;
    let method = s.methods.get(s.current).map_or("-", |m| m.name());
    let others: Vec<String> = s
        .methods
        .iter()
        .enumerate()
        .map(|(n, m)| format!("{} {}", n + 1, m.name()))
        .collect();
    let target = match s.target {
        Target::Tolerance(e) => format!("eps {e:.3} px"),
        Target::Budget(b) => format!("budget {b} points"),
    };
    let mode = match s.mode {
        Mode::Fly => format!("fly {:.2} R/s", s.speed),
        Mode::Orbit => "orbit".into(),
    };
    let gpu = match (i.stats.gpu_ms, s.timestamps) {
        (Some(ms), _) => format!("{ms:.2} ms"),
        (None, false) => "n/a (no timestamps)".into(),
        (None, true) => "-".into(),
    };
    let drawn = i.stats.gpu_passed.unwrap_or(i.stats.points);
    let fps = if i.frame_ms > 0.0 {
        1e3 / i.frame_ms
    } else {
        0.0
    };
    let flip = match i.flip {
        Some((f, v)) => format!("FLIP {v:.4} (frame {f})"),
        None => "FLIP: press C".into(),
    };
    let loader = match &i.traffic {
        Some(t) => format!(
            "loader: {} requests, {} read, {} failed tries, {} chunks missing",
            t.issued,
            mib(t.bytes),
            t.failed,
            i.failed_chunks
        ),
        None => "loader: in core".into(),
    };
    let play = match s.playing {
        Some((f, n)) => format!("  playing {f}/{n}"),
        None => String::new(),
    };
    vec![
        format!("{method}  [{}]", others.join(", ")),
        format!(
            "{target}  kernel {}  raster {}  {mode}{play}",
            s.settings.kernel.name(),
            s.settings.raster.name()
        ),
        format!(
            "points {drawn}  chunks {}  cpu select {:.2} ms  gpu {gpu}",
            i.stats.chunks, i.cpu_select_ms
        ),
        format!(
            "frame {:.1} ms ({fps:.1} fps)  draw {:.1} ms  upload {}  gpu cache {}",
            i.frame_ms,
            i.stats.wall_ms,
            mib(i.stats.upload_bytes),
            mib(i.stats.cache_bytes)
        ),
        format!(
            "{flip}  showing {}{}  {loader}",
            s.overlay.name(),
            if s.levels { ", levels coloured" } else { "" }
        ),
        format!(
            "keyframes {} (Space add, Enter save, P play)  F12 screenshot  {}",
            s.keyframes, s.message
        ),
    ]
}

/// Lines of [`lines`] that carry per-frame measurements (points, times, bytes): they are
/// redrawn at most every [`REFRESH_S`]; a change in any other line (the method, the target,
/// a message) is drawn at once.
pub const MEASUREMENT_LINES: [usize; 2] = [2, 3];

/// Seconds between redraws of the measurement lines: 4 a second, readable, and on a fast GPU
/// the HUD's text (≈ 1.6 ms on the CPU at 1100 px, `results/measurements/issue-19-viewer.md`)
/// is then drawn on a fraction of the frames instead of every one.
pub const REFRESH_S: f64 = 0.25;

/// Whether the HUD drawn at `drawn_at` seconds from `drawn` must be redrawn at `now` to show
/// `lines`.
pub fn needs_redraw(drawn: Option<(&[String], f64)>, lines: &[String], now: f64) -> bool {
    let Some((old, at)) = drawn else {
        return true;
    };
    if old.len() != lines.len() {
        return true;
    }
    let changed = |i: usize| old[i] != lines[i];
    (0..lines.len()).any(|i| changed(i) && !MEASUREMENT_LINES.contains(&i))
        || (now - at >= REFRESH_S && (0..lines.len()).any(changed))
}

/// Text height, pixels.
pub const LINE_PX: u32 = 16;

/// Left and right margin of the text, pixels.
const MARGIN_PX: u32 = 6;

/// `lines` broken so that each fits a panel `width` pixels wide in the HUD's font: a line too
/// wide is broken at its field separators (two spaces) into as few lines as fit; a single
/// field wider than the panel keeps a line of its own. At the default 512 px window the
/// HUD's six lines of 600–700 px were cut at the right edge.
pub fn fit(lines: &[String], width: u32) -> anyhow::Result<Vec<String>> {
    crate::plot::ensure_font()?;
    let font = (crate::plot::FONT, LINE_PX as f64 * 0.85).into_font();
    let room = width.saturating_sub(2 * MARGIN_PX);
    let px = |t: &str| -> anyhow::Result<u32> {
        Ok(font
            .box_size(t)
            .map_err(|e| anyhow::anyhow!("HUD: {e:?}"))?
            .0)
    };
    let mut out = Vec::new();
    for line in lines {
        if px(line)? <= room {
            out.push(line.clone());
            continue;
        }
        let mut current = String::new();
        for field in line.split("  ").filter(|f| !f.is_empty()) {
            let joined = if current.is_empty() {
                field.to_string()
            } else {
                format!("{current}  {field}")
            };
            if current.is_empty() || px(&joined)? <= room {
                current = joined;
            } else {
                out.push(std::mem::replace(&mut current, field.to_string()));
            }
        }
        out.push(current);
    }
    Ok(out)
}

/// `lines` in white on a dark panel `width` pixels wide (opaque RGBA, one [`LINE_PX`] row
/// per line plus a margin), broken to fit the width first ([`fit`]).
pub fn draw(lines: &[String], width: u32) -> anyhow::Result<Image> {
    let lines = fit(lines, width)?;
    let height = LINE_PX * lines.len() as u32 + 8;
    let mut rgb = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        root.fill(&RGBColor(16, 16, 24))
            .map_err(|e| anyhow::anyhow!("HUD: {e}"))?;
        let style = (crate::plot::FONT, LINE_PX as f64 * 0.85)
            .into_font()
            .color(&WHITE);
        for (n, l) in lines.iter().enumerate() {
            root.draw(&Text::new(
                l.as_str(),
                (MARGIN_PX as i32, 4 + (n as u32 * LINE_PX) as i32),
                &style,
            ))
            .map_err(|e| anyhow::anyhow!("HUD: {e}"))?;
        }
        root.present().map_err(|e| anyhow::anyhow!("HUD: {e}"))?;
    }
    let rgba = rgb
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    Ok(Image::from_rgba(width, height, rgba)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::FrameStats;

    #[test]
    fn measurements_refresh_four_times_a_second_and_the_rest_at_once() {
        let l = |a: &str, t: &str| -> Vec<String> {
            ["m", "eps", a, t, "flip", "keys"]
                .map(String::from)
                .to_vec()
        };
        let old = l("points 1", "frame 1 ms");
        assert!(needs_redraw(None, &old, 0.0));
        let new_times = l("points 2", "frame 2 ms");
        assert!(!needs_redraw(Some((&old, 0.0)), &new_times, 0.1));
        assert!(needs_redraw(Some((&old, 0.0)), &new_times, REFRESH_S));
        assert!(
            !needs_redraw(Some((&old, 0.0)), &old, 10.0),
            "nothing changed"
        );
        let mut message = old.clone();
        message[5] = "keys saved".into();
        assert!(
            needs_redraw(Some((&old, 0.0)), &message, 0.01),
            "a message shows at once"
        );
    }

    fn state(info: &FrameInfo) -> HudState<'_> {
        HudState {
            methods: vec![MethodKind::Qsplat, MethodKind::Spt],
            current: 1,
            target: Target::Tolerance(2.0),
            settings: RenderSettings::default(),
            info,
            overlay: Overlay::Holes,
            levels: true,
            mode: Mode::Fly,
            speed: 0.5,
            keyframes: 2,
            playing: None,
            message: "saved",
            timestamps: false,
        }
    }

    #[test]
    fn the_hud_reports_the_frame_and_draws_legibly() {
        let info = FrameInfo {
            stats: FrameStats {
                points: 1000,
                gpu_passed: Some(750),
                chunks: 3,
                gpu_ms: None,
                upload_bytes: 3 << 20,
                ..Default::default()
            },
            cpu_select_ms: 1.5,
            frame_ms: 20.0,
            flip: Some((7, 0.0123)),
            ..Default::default()
        };
        let l = lines(&state(&info));
        assert!(l[0].starts_with("spt  [1 qsplat, 2 spt]"), "{}", l[0]);
        assert!(l[1].starts_with("eps 2.000 px  kernel square"), "{}", l[1]);
        assert!(
            l[2].contains("points 750 ") && l[2].contains("gpu n/a (no timestamps)"),
            "the GPU's count, and no GPU time without timestamps: {}",
            l[2]
        );
        assert!(
            l[3].contains("(50.0 fps)") && l[3].contains("upload 3.0 MiB"),
            "{}",
            l[3]
        );
        assert!(
            l[4].contains("FLIP 0.0123 (frame 7)")
                && l[4].contains("showing holes, levels coloured")
        );
        // A method that loads: the loader's figures make the fifth line the longest.
        let loading = FrameInfo {
            traffic: Some(methods::store::access::Traffic {
                issued: 12_345,
                bytes: 123 << 20,
                failed: 2,
                ..Default::default()
            }),
            failed_chunks: 1,
            ..info.clone()
        };
        let long = lines(&HudState {
            methods: vec![MethodKind::Qsplat, MethodKind::Lpc, MethodKind::Mwkd],
            info: &loading,
            message: "saved 3 keyframes to /home/user/.local/share/splatbench/view/path.toml",
            ..state(&loading)
        });
        assert!(l[5].starts_with("keyframes 2") && l[5].ends_with("saved"));
        let img = draw(&l, 1100).expect("drawn");
        assert_eq!((img.width, img.height), (1100, 16 * 6 + 8));
        let bright = img.rgba.chunks_exact(4).filter(|p| p[0] > 128).count();
        assert!(bright > 500, "text drawn: {bright} bright pixels");
        // At the default 512 px window no line is cut: long lines are broken at their
        // fields, and every field of the original lines is still there, in order.
        let narrow = fit(&long, 512).expect("fitted");
        assert!(narrow.len() > long.len(), "{narrow:#?}");
        let font = (crate::plot::FONT, LINE_PX as f64 * 0.85).into_font();
        for line in &narrow {
            let w = font.box_size(line).expect("measured").0;
            assert!(w <= 512 - 2 * MARGIN_PX, "{w} px: {line}");
        }
        let fields = |ls: &[String]| -> Vec<String> {
            ls.iter()
                .flat_map(|x| x.split("  ").map(String::from).collect::<Vec<_>>())
                .filter(|f| !f.is_empty())
                .collect()
        };
        assert_eq!(fields(&narrow), fields(&long));
        let img = draw(&long, 512).expect("drawn");
        assert_eq!(img.height, 16 * narrow.len() as u32 + 8);
    }
}
