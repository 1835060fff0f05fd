//! How splats are shaded (`--shading`), the same for the reference and every method's frames.
//!
//! | mode | colour | light |
//! |------|--------|-------|
//! | `lambert` | the scene's colour, else [`super::BASE_COLOR`] | Lambert headlight, two-sided, ambient [`super::AMBIENT`], when the splat has a normal; none without |
//! | `colour` | the scene's colour, else the base colour | none (the colour as stored) |
//! | `edl` | as `colour` | eye-dome lighting ([`super::edl`]), from depth only |
//! | `elevation` | [`elevation_colour`] of the height (+Z after `--up`) over the framed box | none |
//! | `intensity`, `classification` | the scalar, turned into the cloud's colour at load ([`scenes::scalar`]) | none |
//!
//! `auto` (the default) is resolved per scene by [`Shading::resolve`]: `lambert` when the
//! scene has normals, `colour` when it has colours but no normals, `edl` when it has neither
//! — a bare LiDAR tile then shows its structure instead of a flat white silhouette, as
//! Potree and CloudCompare show it. The resolved mode is what results record.
//!
//! Intensity and classification reach the methods as colour (so every method stores and
//! draws them as it does colour, and a run without them never reads them); elevation is
//! computed in the shader from the position, so no method stores anything for it.

use scenes::{Attributes, Scalar};

/// The `--shading` modes (see the module docs).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Hash,
    Default,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Shading {
    /// Resolved from the scene's attributes (see `Shading::resolve`).
    #[default]
    Auto,
    /// Lambert headlight on the normals (flat without normals).
    Lambert,
    /// The colours as stored, unlit.
    Colour,
    /// Eye-dome lighting on the unlit colour: screen-space, from depth only.
    Edl,
    /// A colour ramp over the height.
    Elevation,
    /// Grey from the file's intensity.
    Intensity,
    /// The ASPRS class palette from the file's classification.
    Classification,
}

impl Shading {
    /// Every mode.
    pub const ALL: &'static [Shading] = &[
        Shading::Auto,
        Shading::Lambert,
        Shading::Colour,
        Shading::Edl,
        Shading::Elevation,
        Shading::Intensity,
        Shading::Classification,
    ];

    /// The name (`--shading`, results).
    pub fn name(self) -> &'static str {
        match self {
            Shading::Auto => "auto",
            Shading::Lambert => "lambert",
            Shading::Colour => "colour",
            Shading::Edl => "edl",
            Shading::Elevation => "elevation",
            Shading::Intensity => "intensity",
            Shading::Classification => "classification",
        }
    }

    /// The file scalar this mode colours by, which the scene must be loaded with
    /// ([`scenes::SceneSpec::with_colour_from`]).
    pub fn scalar(self) -> Option<Scalar> {
        match self {
            Shading::Intensity => Some(Scalar::Intensity),
            Shading::Classification => Some(Scalar::Classification),
            _ => None,
        }
    }

    /// `auto` for a scene with `attrs`: `lambert` with normals, else `colour` with colours,
    /// else `edl`; any other mode as it is.
    pub fn resolve(self, attrs: Attributes) -> Shading {
        match self {
            Shading::Auto if attrs.normals => Shading::Lambert,
            Shading::Auto if attrs.colors => Shading::Colour,
            Shading::Auto => Shading::Edl,
            s => s,
        }
    }

    /// The shader's `frame.shading` code: 0 lit, 1 unlit, 2 elevation ramp.
    pub fn shader_code(self) -> u32 {
        match self {
            Shading::Auto | Shading::Lambert => 0,
            Shading::Elevation => 2,
            _ => 1,
        }
    }
}

impl std::fmt::Display for Shading {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A renderer's per-frame drawing settings: the shading mode and, for `elevation`, the heights
/// that map to the two ends of the ramp (the runner uses the framed box's Z range, so far
/// strays do not flatten it); the ellipse kernel's clamp.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Shade {
    /// The mode; `auto` here draws as `lambert` (resolve it first to get `edl`).
    pub shading: Shading,
    /// Local Z at the bottom and top of the elevation ramp.
    pub elevation: [f32; 2],
    /// The largest major ÷ minor axis ratio of an elliptical splat (`--ellipse-clamp`;
    /// QSplat §3.3's 10, [`ELLIPSE_CLAMP`]): the minor axis is `max(|n̂·v̂|, 1/clamp)` of the
    /// major. At least 1 (1: circles).
    pub ellipse_clamp: f32,
}

/// QSplat §3.3: "clamping the maximum ratio of major to minor axis to 10 fills in
/// practically all of these holes".
pub const ELLIPSE_CLAMP: f32 = 10.0;

impl Default for Shade {
    fn default() -> Self {
        Self {
            shading: Shading::Auto,
            elevation: [0.0, 1.0],
            ellipse_clamp: ELLIPSE_CLAMP,
        }
    }
}

impl Shade {
    /// The smallest minor ÷ major axis ratio of an ellipse (`1 / ellipse_clamp`).
    pub fn ellipse_min_ratio(&self) -> f32 {
        1.0 / self.ellipse_clamp
    }

    /// `clamp` as an ellipse clamp ([`Shade::ellipse_clamp`]), or why not: the one check
    /// behind `--ellipse-clamp` and [`super::Renderer::new`].
    pub fn check_ellipse_clamp(clamp: f32) -> Result<f32, String> {
        if clamp.is_finite() && clamp >= 1.0 {
            Ok(clamp)
        } else {
            Err(format!(
                "--ellipse-clamp {clamp}: the largest major ÷ minor axis ratio must be a finite \
                 number ≥ 1"
            ))
        }
    }

    /// `1 / (top − bottom)` of the elevation ramp, 0 for an empty range (every height then
    /// takes the ramp's first colour).
    pub fn elevation_scale(&self) -> f32 {
        let d = self.elevation[1] - self.elevation[0];
        if d.is_finite() && d > 0.0 {
            1.0 / d
        } else {
            0.0
        }
    }
}

/// The elevation ramp's stops, sRGB8: five samples of matplotlib's *viridis* (perceptually
/// uniform, monotonic in lightness, readable by colour-blind viewers), interpolated linearly
/// in sRGB between them.
pub const ELEVATION_STOPS: [[f32; 3]; 5] = [
    [68.0, 1.0, 84.0],
    [59.0, 82.0, 139.0],
    [33.0, 145.0, 140.0],
    [94.0, 201.0, 98.0],
    [253.0, 231.0, 37.0],
];

/// The sRGB colour (0–1 per channel) of ramp position `t` (clamped to 0–1), as
/// `splat.wgsl`'s `elevation_colour` computes it.
pub fn elevation_colour(t: f32) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0) * 4.0;
    let i = (t.floor() as usize).min(3);
    let f = t - i as f32;
    let (a, b) = (ELEVATION_STOPS[i], ELEVATION_STOPS[i + 1]);
    [0, 1, 2].map(|c| (a[c] + (b[c] - a[c]) * f) / 255.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_resolves_from_the_attributes() {
        let a = |normals, colors| Attributes {
            normals,
            colors,
            radii: false,
        };
        assert_eq!(Shading::Auto.resolve(a(true, true)), Shading::Lambert);
        assert_eq!(Shading::Auto.resolve(a(false, true)), Shading::Colour);
        assert_eq!(Shading::Auto.resolve(a(false, false)), Shading::Edl);
        for &s in &Shading::ALL[1..] {
            assert_eq!(s.resolve(a(false, false)), s);
        }
    }

    /// `splat.wgsl` spells the ramp's stops out; they must be these.
    #[test]
    fn shader_ramp_is_the_rust_ramp() {
        let stops: Vec<String> = ELEVATION_STOPS
            .iter()
            .map(|c| format!("vec3<f32>({:.1}, {:.1}, {:.1})", c[0], c[1], c[2]))
            .collect();
        let wgsl = super::super::SPLAT_WGSL;
        let at = wgsl.find("const RAMP").expect("RAMP in splat.wgsl");
        let ramp = &wgsl[at..at + wgsl[at..].find(");").unwrap()];
        assert_eq!(ramp.matches("vec3<f32>(").count(), stops.len(), "{ramp}");
        for s in &stops {
            assert!(ramp.contains(s.as_str()), "{s} not in {ramp}");
        }
    }

    #[test]
    fn ramp_hits_its_stops_and_clamps() {
        for (i, stop) in ELEVATION_STOPS.iter().enumerate() {
            let c = elevation_colour(i as f32 / 4.0);
            for k in 0..3 {
                assert!((c[k] * 255.0 - stop[k]).abs() < 1e-3, "stop {i}");
            }
        }
        assert_eq!(elevation_colour(-3.0), elevation_colour(0.0));
        assert_eq!(elevation_colour(7.0), elevation_colour(1.0));
        let mid = elevation_colour(0.125);
        assert!((mid[2] * 255.0 - (84.0 + 139.0) / 2.0).abs() < 1e-3);
        assert_eq!(Shade::default().elevation_scale(), 1.0);
        let flat = Shade {
            elevation: [2.0, 2.0],
            ..Shade::default()
        };
        assert_eq!(flat.elevation_scale(), 0.0);
    }
}
