//! Full-resolution reference images: the `full` method's frames of a run's views, rendered
//! once per scene, view and renderer setting and cached on disk, keyed by all of them.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use methods::{BuildStats, Feedback, LodMethod, MethodKind, Params, Target};
use scenes::{PointCloud, Progress, View};

use super::REFERENCE_VERSION;
use crate::gpu::Gpu;
use crate::image::Image;
use crate::metrics::warp::DepthImage;
use crate::render::{RenderSettings, Renderer};

/// Full-resolution reference images, cached on disk.
pub struct Reference<'g> {
    gpu: &'g Gpu,
    cloud: &'g PointCloud,
    scene_label: String,
    scene_hash: u64,
    cache: PathBuf,
    settings: RenderSettings,
    full: Option<(Box<dyn LodMethod>, Renderer<'g>)>,
}

impl<'g> Reference<'g> {
    /// A reference source for `cloud` (whose content hash is `scene_hash`).
    pub fn new(
        gpu: &'g Gpu,
        cloud: &'g PointCloud,
        scene_label: String,
        scene_hash: u64,
        cache: &Path,
        settings: RenderSettings,
    ) -> Self {
        Self {
            gpu,
            cloud,
            scene_label,
            scene_hash,
            cache: cache.to_path_buf(),
            settings,
            full: None,
        }
    }

    fn full_dir(&self) -> PathBuf {
        self.cache
            .join("full")
            .join(format!("{:016x}", self.scene_hash))
    }

    /// How many leaf radii the reference build capped as isolated (`None` before the first
    /// image was rendered or when its build records none).
    pub fn radii_capped(&self) -> Option<u64> {
        BuildStats::read(&self.full_dir())
            .ok()?
            .extra
            .get("leaf_radii_capped")?
            .as_u64()
    }

    fn key(&self, view: &View) -> String {
        let mut h = scenes::hash::Fnv64::default();
        // The ellipse clamp is keyed below, only when it is not the default: the keys of the
        // references made before it was a setting (its bytes were padding, 0) stay valid.
        let mut uniform = crate::render::frame_uniform(view, &self.settings.shade);
        uniform.ellipse_min_ratio = 0.0;
        h.write(&self.scene_hash.to_le_bytes())
            .write(bytemuck::bytes_of(&uniform))
            .write_str(self.settings.shade.shading.name())
            .write(&view.camera.near.to_le_bytes())
            .write(&view.camera.far.to_le_bytes())
            .write_str(self.settings.kernel.name())
            // Rasterisers differ by a pixel here and there: a reference is its adapter's.
            .write_str(&self.gpu.adapter.name)
            .write_str(&self.gpu.adapter.backend)
            .write(&REFERENCE_VERSION.to_le_bytes())
            .write(&crate::render::image_shaders_hash().to_le_bytes());
        // The rasteriser, for compute only: quads keys stay those of the references made
        // before the compute rasteriser existed.
        if self.settings.raster != crate::render::Raster::Quads {
            h.write_str(self.settings.raster.name());
        }
        if self.settings.shade.ellipse_clamp != crate::render::ELLIPSE_CLAMP {
            h.write(&self.settings.shade.ellipse_clamp.to_le_bytes());
        }
        format!("{:016x}", h.finish())
    }

    /// Builds the `full` reference into `dir` through a temporary directory of this process,
    /// renamed into place: processes sharing a cache (parallel jobs) never write into one
    /// directory, and a reader sees a complete build or none. A directory left without a
    /// manifest (an interrupted build) is replaced; one that appeared meanwhile is kept.
    fn build_full(&self, dir: &Path, progress: &dyn Progress) -> anyhow::Result<()> {
        let mut tmp = dir.as_os_str().to_owned();
        tmp.push(format!(".tmp.{}", std::process::id()));
        let tmp = PathBuf::from(tmp);
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp)
                .with_context(|| format!("removing the old {}", tmp.display()))?;
        }
        MethodKind::Full
            .build(
                self.cloud,
                &Params::default(),
                &self.scene_label,
                &tmp,
                progress,
            )
            .context("building the full-resolution reference")?;
        if dir.exists() && methods::Manifest::read(dir).is_err() {
            std::fs::remove_dir_all(dir)
                .with_context(|| format!("removing the unfinished {}", dir.display()))?;
        }
        if std::fs::rename(&tmp, dir).is_err() {
            // Another process put its (identical) build there first.
            methods::Manifest::read(dir).with_context(|| {
                format!("moving the reference build {} into place", tmp.display())
            })?;
            std::fs::remove_dir_all(&tmp).ok();
        }
        Ok(())
    }

    fn cached(&self, view: &View, ext: &str) -> PathBuf {
        self.cache
            .join("refs")
            .join(format!("{}.{ext}", self.key(view)))
    }

    /// The reference image of `view` (rendered and cached if missing).
    pub fn image(&mut self, view: &View, progress: &dyn Progress) -> anyhow::Result<Image> {
        // A cached image that fails to load (e.g. truncated by a crash) is re-rendered.
        if let Ok(img) = Image::load_png(&self.cached(view, "png")) {
            return Ok(img);
        }
        Ok(self.render(view, progress)?.0)
    }

    /// The reference image of `view` and its depth (rendered and cached if either is
    /// missing or fails to load): what the warped popping metric reprojects with.
    pub fn frame(
        &mut self,
        view: &View,
        progress: &dyn Progress,
    ) -> anyhow::Result<(Image, DepthImage)> {
        if let (Ok(img), Ok(depth)) = (
            Image::load_png(&self.cached(view, "png")),
            DepthImage::load(&self.cached(view, "depth")),
        ) && (depth.width, depth.height) == (view.width, view.height)
        {
            return Ok((img, depth));
        }
        self.render(view, progress)
    }

    /// Renders the reference of `view` and caches its image and depth.
    fn render(
        &mut self,
        view: &View,
        progress: &dyn Progress,
    ) -> anyhow::Result<(Image, DepthImage)> {
        if self.full.is_none() {
            let dir = self.full_dir();
            if methods::Manifest::read(&dir).is_err() {
                self.build_full(&dir, progress)?;
            }
            let m = MethodKind::open(&dir)?;
            let mut r = Renderer::new(
                self.gpu,
                RenderSettings {
                    cache_bytes: self.settings.cache_bytes,
                    ..self.settings
                },
            )?;
            r.keep_depth(true);
            self.full = Some((m, r));
        }
        let Some((m, r)) = self.full.as_mut() else {
            anyhow::bail!("reference renderer missing");
        };
        let list = m.frame(view, Target::Tolerance(1.0), &Feedback::default())?;
        let (_, img) = r.draw(view, &list, m.as_ref(), true)?;
        let img = img.context("reference readback")?;
        let depth = r.read_depth(view).context("reference depth readback")?;
        let (png, dep) = (self.cached(view, "png"), self.cached(view, "depth"));
        std::fs::create_dir_all(png.parent().unwrap_or(&self.cache))
            .with_context(|| format!("creating {}", self.cache.display()))?;
        img.save_png(&png)?;
        depth
            .save(&dep)
            .with_context(|| format!("writing {}", dep.display()))?;
        Ok((img, depth))
    }
}
