//! The viewer without its window: methods opened on one scene, the camera, the keyframe
//! recorder and the toggles; each [`Session::frame`] draws through the same [`Renderer`] and
//! draw lists as `run`, so what the window shows is what `run` measures. The window
//! ([`super::window`]) only feeds events in and presents [`Session::display`]; tests drive a
//! session headless.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use methods::{LodMethod, MethodKind, Params, Target};
use scenes::paths::PathSpec;
use scenes::{Camera, Progress, View};

use super::command::{Action, Effect, Event, effect};
use super::control::Controller;
pub use super::hud::{FrameInfo, Overlay};
use super::overlay;
use super::record::{Recorder, still};
use crate::gpu::Gpu;
use crate::image::Image;
use crate::render::{FrameStats, Kernel, Raster, RenderSettings, Renderer};
use crate::runner::{
    BuildSource, PreparedScene, Reference, check_gpu_budget, next_feedback, open_method,
};

/// Why FLIP is refused while levels are coloured.
const FLIP_NEEDS_COLOURS: &str =
    "FLIP compares the method's own colours with the reference: turn level colours off (L)";

/// Factor per `+`/`−` press: ε ÷ / × √2, budget × / ÷ √2.
pub const TARGET_STEP: f64 = std::f64::consts::SQRT_2;

/// What the viewer is asked to show.
#[derive(Debug, Clone)]
pub struct SessionConfig {
    /// The methods (keys 1…9), with their parameters.
    pub methods: Vec<(MethodKind, Params)>,
    /// An existing build of the (single) method (`--build-dir`).
    pub build_dir: Option<PathBuf>,
    /// Tolerance or budget at start.
    pub target: Target,
    /// Cache directory (scenes, reference builds and images).
    pub cache: PathBuf,
    /// Where builds, screenshots and recorded paths go.
    pub out: PathBuf,
    /// The path `P` plays (`--play`); without it, the last one saved.
    pub play: Option<PathSpec>,
    /// Frames a played path takes (`run --frames` of the same path draws the same poses).
    pub play_frames: usize,
    /// The scene's flags as `run` takes them (`--scene S [--sample N] [--seed N] [--up A]
    /// [--keep-attributes]`), for the run command written beside screenshots.
    pub scene_flags: String,
}

struct Slot {
    kind: MethodKind,
    params: Params,
    method: Box<dyn LodMethod>,
}

/// Where a shown image comes from.
pub enum Display<'a> {
    /// The renderer's colour target.
    Target(&'a wgpu::TextureView),
    /// An image made on the CPU (reference, FLIP map, hole mask), with a generation number
    /// that changes with its content.
    Image(&'a Image, u64),
}

/// Files a screenshot wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Shot {
    /// The frame.
    pub frame: PathBuf,
    /// The reference at the same pose.
    pub reference: PathBuf,
    /// The pose as a camera path (`run --path`).
    pub sidecar: PathBuf,
}

/// The viewer's state.
pub struct Session<'g> {
    gpu: &'g Gpu,
    scene: &'g PreparedScene,
    cfg: SessionConfig,
    slots: Vec<Slot>,
    current: usize,
    renderer: Renderer<'g>,
    reference: Reference<'g>,
    /// The camera.
    pub control: Controller,
    recorder: Recorder,
    target: Target,
    overlay: Overlay,
    levels: bool,
    shown: Option<(Image, u64)>,
    generation: u64,
    playback: Option<(PathSpec, usize)>,
    saved: Vec<PathBuf>,
    last: Option<(FrameStats, View)>,
    frame_no: u64,
    clock: f64,
    pending_shot: bool,
    pending_flip: bool,
    quit: bool,
    /// What the last frame cost.
    pub info: FrameInfo,
    /// The last thing done or refused, for the HUD.
    pub message: String,
    /// Screenshots taken.
    pub shots: Vec<Shot>,
}

impl<'g> Session<'g> {
    /// Opens (building where needed) every method of `cfg` on `scene`.
    pub fn new(
        gpu: &'g Gpu,
        scene: &'g PreparedScene,
        cfg: SessionConfig,
        progress: &dyn Progress,
    ) -> anyhow::Result<Self> {
        anyhow::ensure!(!cfg.methods.is_empty(), "no method to view");
        anyhow::ensure!(
            cfg.methods.len() <= 9,
            "--methods lists {} methods: keys 1 to 9 select at most 9",
            cfg.methods.len()
        );
        anyhow::ensure!(
            cfg.build_dir.is_none() || cfg.methods.len() == 1,
            "--build-dir holds one method's build: give --method, not --methods"
        );
        anyhow::ensure!(cfg.play_frames >= 2, "--play-frames must be at least 2");
        let render = scene.render;
        // The viewer draws a reference and FLIP for its HUD: the frame's images with metrics.
        crate::memory::check_frame(&render, true)?;
        let mut slots = Vec::new();
        for (kind, params) in &cfg.methods {
            kind.check_params(params)?;
            let into = build_dir_for(&cfg.out, *kind, params, scene);
            let source = match &cfg.build_dir {
                Some(dir) => BuildSource::Dir(dir),
                None if reusable(&into, *kind, params, scene) => BuildSource::Dir(&into),
                None => BuildSource::Build(&into),
            };
            let opened = open_method(*kind, params, scene, source, progress)?;
            check_gpu_budget(*kind, opened.method.as_ref(), render.cache_bytes)?;
            slots.push(Slot {
                kind: *kind,
                params: params.clone(),
                method: opened.method,
            });
        }
        std::fs::create_dir_all(&cfg.out)
            .with_context(|| format!("creating {}", cfg.out.display()))?;
        let renderer = Renderer::new(gpu, render)?;
        let reference = new_reference(gpu, scene, &cfg.cache, render);
        Ok(Session {
            gpu,
            scene,
            control: Controller::new(&scene.bounds),
            target: cfg.target.validate()?,
            cfg,
            slots,
            current: 0,
            renderer,
            reference,
            recorder: Recorder::default(),
            overlay: Overlay::Method,
            levels: false,
            shown: None,
            generation: 0,
            playback: None,
            saved: Vec::new(),
            last: None,
            frame_no: 0,
            clock: 0.0,
            pending_shot: false,
            pending_flip: false,
            quit: false,
            info: FrameInfo::default(),
            message: String::new(),
            shots: Vec::new(),
        })
    }

    /// True once quit was asked for.
    pub fn quit_requested(&self) -> bool {
        self.quit
    }

    /// Frames drawn.
    pub fn frames(&self) -> u64 {
        self.frame_no
    }

    /// The renderer's settings (size, kernel, raster).
    pub fn settings(&self) -> RenderSettings {
        self.renderer.settings()
    }

    /// The method shown.
    pub fn method(&self) -> MethodKind {
        self.slots[self.current].kind
    }

    /// The target in force.
    pub fn target(&self) -> Target {
        self.target
    }

    /// Whether chunks are coloured by level.
    pub fn level_colours(&self) -> bool {
        self.levels
    }

    /// The image shown.
    pub fn overlay(&self) -> Overlay {
        self.overlay
    }

    /// Keyframes recorded so far.
    pub fn keyframes(&self) -> usize {
        self.recorder.len()
    }

    /// Whether a path is playing.
    pub fn playing(&self) -> bool {
        self.playback.is_some()
    }

    /// The camera the next frame draws (the played path's pose while one plays).
    pub fn camera(&self) -> Camera {
        match &self.playback {
            Some((path, i)) => path.camera(*i, self.cfg.play_frames, &self.scene.bounds),
            None => self.control.camera(),
        }
    }

    /// The paths saved (Enter), in order.
    pub fn saved_paths(&self) -> &[PathBuf] {
        &self.saved
    }

    /// The methods, in key order.
    pub fn methods(&self) -> Vec<MethodKind> {
        self.slots.iter().map(|s| s.kind).collect()
    }

    /// Applies one event (before the next frame is drawn).
    pub fn event(&mut self, ev: &Event) -> anyhow::Result<()> {
        match effect(ev) {
            Effect::Camera(input) => {
                if self.playback.take().is_some() {
                    self.message = "playback stopped".into();
                }
                self.control.input(input);
            }
            Effect::Act(a) => self.act(a)?,
            Effect::None => {}
        }
        Ok(())
    }

    fn act(&mut self, a: Action) -> anyhow::Result<()> {
        match a {
            Action::Move(_) => {}
            Action::ToggleMode => self.control.toggle_mode(),
            Action::Reset => {
                self.playback = None;
                self.control.reset();
            }
            Action::Method(n) if n < self.slots.len() => {
                if n != self.current {
                    self.current = n;
                    self.renderer.clear_cache();
                    self.last = None;
                    self.info.flip = None;
                    self.info.failed_chunks = 0;
                }
            }
            Action::Method(n) => {
                self.message = format!("no method {}: --methods lists {}", n + 1, self.slots.len())
            }
            Action::Finer => self.target = step_target(self.target, true)?,
            Action::Coarser => self.target = step_target(self.target, false)?,
            Action::Kernel => self.next_kernel()?,
            Action::Reference => self.toggle(Overlay::Reference),
            Action::FlipMap if self.levels => self.message = FLIP_NEEDS_COLOURS.into(),
            Action::FlipMap => self.toggle(Overlay::Flip),
            Action::Holes => self.toggle(Overlay::Holes),
            Action::Levels => {
                let slot = &self.slots[self.current];
                // Node-drawing methods number their root chunk 0; a method without levels
                // answers None for every chunk.
                if !self.levels && self.overlay == Overlay::Flip {
                    self.message = FLIP_NEEDS_COLOURS.into();
                } else if !self.levels && slot.method.chunk_level(0).is_none() {
                    self.message = format!(
                        "{} draws splats of every level together: no nodes to colour by level",
                        slot.kind
                    );
                } else {
                    self.levels = !self.levels;
                    self.renderer.set_level_colours(self.levels);
                }
            }
            Action::Measure if self.levels => self.message = FLIP_NEEDS_COLOURS.into(),
            Action::Measure => self.pending_flip = true,
            Action::AddKey => {
                let cam = self.camera();
                match self.recorder.add(self.clock, cam) {
                    Ok(()) => self.message = format!("keyframe {} added", self.recorder.len()),
                    Err(e) => self.message = e,
                }
            }
            Action::SavePath => self.save_path()?,
            Action::Play => self.play(),
            Action::Screenshot => self.pending_shot = true,
            Action::Quit => self.quit = true,
        }
        Ok(())
    }

    fn toggle(&mut self, o: Overlay) {
        self.overlay = if self.overlay == o {
            Overlay::Method
        } else {
            o
        };
    }

    fn next_kernel(&mut self) -> anyhow::Result<()> {
        let s = self.renderer.settings();
        if s.raster == Raster::Compute {
            self.message = "--raster compute draws square splats only".into();
            return Ok(());
        }
        let all = Kernel::ALL;
        let at = all.iter().position(|k| *k == s.kernel).unwrap_or(0);
        let kernel = all[(at + 1) % all.len()];
        let render = RenderSettings { kernel, ..s };
        self.renderer = Renderer::new(self.gpu, render)?;
        self.renderer.set_level_colours(self.levels);
        self.reference = new_reference(self.gpu, self.scene, &self.cfg.cache, render);
        self.last = None;
        self.message = format!("kernel {}", kernel.name());
        Ok(())
    }

    fn save_path(&mut self) -> anyhow::Result<()> {
        let file = numbered(&self.cfg.out, "path", "toml");
        match self.recorder.save(&file) {
            Ok(_) => {
                self.message = format!(
                    "saved {} keyframes to {}",
                    self.recorder.len(),
                    file.display()
                );
                self.saved.push(file);
                self.recorder = Recorder::default();
            }
            Err(e) => self.message = e.to_string(),
        }
        Ok(())
    }

    fn play(&mut self) {
        let path = match (&self.cfg.play, self.saved.last()) {
            (Some(p), _) => Ok(p.clone()),
            (None, Some(f)) => PathSpec::parse(&f.to_string_lossy()),
            (None, None) => {
                self.message = "nothing to play: save a path (Enter) or give --play".into();
                return;
            }
        };
        match path {
            Ok(p) => {
                self.message = format!("playing {} over {} frames", p.name(), self.cfg.play_frames);
                self.playback = Some((p, 0));
            }
            Err(e) => self.message = e.to_string(),
        }
    }

    /// Draws one frame, `dt` seconds after the last.
    pub fn frame(&mut self, dt: f64, progress: &dyn Progress) -> anyhow::Result<()> {
        let t0 = Instant::now();
        self.clock += dt;
        if self.playback.is_none() {
            self.control.tick(dt);
        }
        let r = self.renderer.settings();
        let view = View {
            camera: self.camera(),
            width: r.width,
            height: r.height,
        };
        if let Some((_, i)) = &mut self.playback {
            // The controller follows, so the user takes over from the pose played last.
            let c = &view.camera;
            self.control
                .look_from(c.position.as_dvec3(), c.target.as_dvec3());
            *i += 1;
            if *i == self.cfg.play_frames {
                self.playback = None;
                self.message = "playback done".into();
            }
        }
        let feedback = next_feedback(self.frame_no, &self.renderer, self.last.as_ref(), &view);
        let slot = &mut self.slots[self.current];
        let t = Instant::now();
        let list = slot
            .method
            .frame(&view, self.target, &feedback)
            .with_context(|| format!("{} frame {}", slot.kind, self.frame_no))?;
        let cpu_select_ms = t.elapsed().as_secs_f64() * 1e3;
        let readback = self.pending_shot || self.pending_flip || self.overlay != Overlay::Method;
        let (stats, img) = self
            .renderer
            .draw(&view, &list, slot.method.as_ref(), readback)?;
        // Each failure once, when it first appears (the list only grows).
        let failed = slot.method.failed_chunks();
        for (id, error) in failed.iter().skip(self.info.failed_chunks) {
            eprintln!("error: {} chunk {id} failed to load: {error}", slot.kind);
        }
        self.info.failed_chunks = failed.len();
        self.info.traffic = slot.method.loads_chunks().then(|| slot.method.traffic());
        self.info.stats = stats.clone();
        self.info.cpu_select_ms = cpu_select_ms;
        self.last = Some((stats, view));
        if let Some(img) = img {
            self.after_readback(&view, img, progress)?;
        } else {
            self.shown = None;
        }
        self.frame_no += 1;
        self.info.frame_ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    fn after_readback(
        &mut self,
        view: &View,
        img: Image,
        progress: &dyn Progress,
    ) -> anyhow::Result<()> {
        let reference = self.reference.image(view, progress)?;
        if std::mem::take(&mut self.pending_flip) {
            let f = crate::metrics::flip_mean(&reference, &img)?;
            self.info.flip = Some((self.frame_no, f));
        }
        if std::mem::take(&mut self.pending_shot) {
            let shot = self.screenshot(view, &img, &reference)?;
            self.message = format!("screenshot {}", shot.frame.display());
            self.shots.push(shot);
        }
        let shown = match self.overlay {
            Overlay::Method => None,
            Overlay::Reference => Some(reference),
            Overlay::Flip => Some(crate::metrics::flip_map(&reference, &img)?),
            Overlay::Holes => Some(overlay::hole_mask(&reference, &img)?),
        };
        self.generation += 1;
        self.shown = shown.map(|i| (i, self.generation));
        Ok(())
    }

    fn screenshot(&self, view: &View, img: &Image, reference: &Image) -> anyhow::Result<Shot> {
        let sidecar = numbered(&self.cfg.out, "shot", "toml");
        let stem = sidecar.with_extension("");
        let frame = stem.with_extension("png");
        let mut ref_name = stem.as_os_str().to_owned();
        ref_name.push("-ref.png");
        let reference_file = PathBuf::from(ref_name);
        img.save_png(&frame)?;
        reference.save_png(&reference_file)?;
        let name = stem
            .file_name()
            .map_or_else(|| "shot".into(), |s| s.to_string_lossy().into_owned());
        let kf = still(&name, &view.camera)?;
        let r = self.renderer.settings();
        let slot = &self.slots[self.current];
        let mut params = String::new();
        for (k, v) in &slot.params.0 {
            params.push_str(&format!(" --param {k}={v}"));
        }
        let target = match self.target {
            Target::Tolerance(e) => format!("--eps {e}"),
            Target::Budget(b) => format!("--budget {b}"),
        };
        let build_dir = match &self.cfg.build_dir {
            Some(d) => format!(" --build-dir {}", d.display()),
            None => String::new(),
        };
        let tinted = if self.levels {
            "# (Taken with levels coloured, the viewer's L: run draws the method's own colours.)\n"
        } else {
            ""
        };
        let text = format!(
            "# A screenshot of `splatbench view` ({}): this pose as a camera path. The same\n\
             # image again:\n\
             # splatbench run {} --method {}{build_dir}{params} {target} --kernel {} --raster {} \
             --width {} --height {} --shading {} --path {} --frames 1 --save-images --out OUT\n\
             {tinted}{}",
            frame.display(),
            self.cfg.scene_flags,
            slot.kind,
            r.kernel.name(),
            r.raster.name(),
            r.width,
            r.height,
            r.shade.shading.name(),
            sidecar.display(),
            kf.to_toml()
        );
        std::fs::write(&sidecar, text).with_context(|| format!("writing {}", sidecar.display()))?;
        Ok(Shot {
            frame,
            reference: reference_file,
            sidecar,
        })
    }

    /// What the window shows now.
    pub fn display(&self) -> Display<'_> {
        match &self.shown {
            Some((img, g)) => Display::Image(img, *g),
            None => Display::Target(self.renderer.color_view()),
        }
    }

    /// The HUD's lines.
    pub fn hud(&self) -> Vec<String> {
        super::hud::lines(&super::hud::HudState {
            methods: self.methods(),
            current: self.current,
            target: self.target,
            settings: self.renderer.settings(),
            info: &self.info,
            overlay: self.overlay,
            levels: self.levels,
            mode: self.control.mode,
            speed: self.control.speed,
            keyframes: self.recorder.len(),
            playing: self
                .playback
                .as_ref()
                .map(|(_, i)| (*i, self.cfg.play_frames)),
            message: &self.message,
            timestamps: self.gpu.timestamps,
        })
    }
}

fn new_reference<'g>(
    gpu: &'g Gpu,
    scene: &'g PreparedScene,
    cache: &Path,
    render: RenderSettings,
) -> Reference<'g> {
    Reference::new(
        gpu,
        &scene.cloud,
        scene.label.clone(),
        scene.hash,
        cache,
        render,
    )
}

/// `dir/NAME-NNN.EXT` for the first NNN not taken.
fn numbered(dir: &Path, name: &str, ext: &str) -> PathBuf {
    (1..)
        .map(|n| dir.join(format!("{name}-{n:03}.{ext}")))
        .find(|p| !p.exists())
        .unwrap_or_else(|| dir.join(format!("{name}.{ext}")))
}

/// The target one `+` (`finer`) or `−` press away.
pub fn step_target(t: Target, finer: bool) -> anyhow::Result<Target> {
    Ok(match t {
        Target::Tolerance(e) => {
            let f = if finer {
                1.0 / TARGET_STEP
            } else {
                TARGET_STEP
            };
            Target::tolerance((f64::from(e) * f) as f32)?
        }
        Target::Budget(b) => {
            let f = if finer {
                TARGET_STEP
            } else {
                1.0 / TARGET_STEP
            };
            Target::budget(((b as f64 * f).round() as u64).max(1))?
        }
    })
}

/// Where the viewer builds `kind` with `params` on `scene`: one directory per method and
/// parameter set under `out/builds/`, reused by the next start.
fn build_dir_for(out: &Path, kind: MethodKind, params: &Params, scene: &PreparedScene) -> PathBuf {
    let mut h = scenes::hash::Fnv64::default();
    h.write(&scene.hash.to_le_bytes());
    for (k, v) in &params.0 {
        h.write_str(k).write_str(v);
    }
    out.join("builds")
        .join(format!("{}-{:016x}", kind.name(), h.finish()))
}

/// True when `dir` holds a finished build of `kind` with `params` on `scene`.
fn reusable(dir: &Path, kind: MethodKind, params: &Params, scene: &PreparedScene) -> bool {
    methods::Manifest::read(dir).is_ok_and(|m| {
        m.method == kind.name()
            && m.scene == scene.label
            && m.points == scene.cloud.len() as u64
            && m.params == *params
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plus_and_minus_step_the_target_by_root_two_and_back() {
        let t = Target::tolerance(1.0).expect("valid");
        let finer = step_target(t, true).expect("valid");
        assert_eq!(finer, Target::tolerance(0.70710677).expect("valid"));
        let back = step_target(finer, false).expect("valid");
        let Target::Tolerance(e) = back else {
            panic!("{back:?}")
        };
        assert!((e - 1.0).abs() < 1e-6);
        let b = Target::budget(100_000).expect("valid");
        assert_eq!(
            step_target(b, true).expect("valid"),
            Target::budget(141_421).expect("valid")
        );
        assert_eq!(
            step_target(Target::budget(1).expect("valid"), false).expect("valid"),
            Target::budget(1).expect("valid"),
            "a budget never reaches 0"
        );
    }

    #[test]
    fn numbered_files_take_the_first_free_number() {
        let dir = tempfile::tempdir().expect("tempdir");
        assert_eq!(
            numbered(dir.path(), "shot", "toml"),
            dir.path().join("shot-001.toml")
        );
        std::fs::write(dir.path().join("shot-001.toml"), "").expect("write");
        assert_eq!(
            numbered(dir.path(), "shot", "toml"),
            dir.path().join("shot-002.toml")
        );
    }
}
