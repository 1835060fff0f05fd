//! `--param key=value` pairs, turned into a method's typed parameters.
//!
//! Values are read as TOML values where they parse (`m=2048` is an integer, `occlusion=true`
//! a bool, `kernel=circle` falls back to a string), then deserialised into the method's
//! `#[serde(deny_unknown_fields)]` struct: a misspelt key is an error naming the key and the
//! keys that exist, never a silent default.

use std::collections::BTreeMap;

use serde::de::DeserializeOwned;

use crate::MethodError;

/// Raw parameters, in the order given (keys unique).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Params(pub BTreeMap<String, String>);

impl Params {
    /// Parses `key=value` strings; a missing `=`, an empty key or a repeated key is an error.
    pub fn parse<S: AsRef<str>>(pairs: &[S]) -> Result<Self, MethodError> {
        let mut map = BTreeMap::new();
        for p in pairs {
            let p = p.as_ref();
            let (k, v) = p
                .split_once('=')
                .ok_or_else(|| MethodError::Param(format!("'{p}' is not key=value")))?;
            let k = k.trim();
            if k.is_empty() {
                return Err(MethodError::Param(format!("'{p}' has an empty key")));
            }
            if map.insert(k.to_string(), v.trim().to_string()).is_some() {
                return Err(MethodError::Param(format!("'{k}' given twice")));
            }
        }
        Ok(Self(map))
    }

    /// Deserialises into `T` (which should use `deny_unknown_fields` and `default`).
    pub fn to_typed<T: DeserializeOwned>(&self, method: &str) -> Result<T, MethodError> {
        let mut table = toml::Table::new();
        for (k, v) in &self.0 {
            let parsed = format!("x = {v}")
                .parse::<toml::Table>()
                .ok()
                .and_then(|mut t| t.remove("x"));
            let digits = v.strip_prefix('-').unwrap_or(v);
            if parsed.is_none() && !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
            {
                // An integer beyond i64 reads as a string and serde would say "invalid type".
                return Err(MethodError::Param(format!(
                    "method '{method}': {k}={v}: the number is out of range (parameters take \
                     integers of at most {})",
                    i64::MAX
                )));
            }
            let value = parsed.unwrap_or_else(|| toml::Value::String(v.clone()));
            table.insert(k.clone(), value);
        }
        T::deserialize(toml::Value::Table(table))
            .map_err(|e| MethodError::Param(format!("method '{method}': {}", e.message())))
    }

    /// True if no parameter was given.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// The default build memory (`mem_mb`) of QSplat, SPT, MWKD and LPC, whose files do not depend
/// on it (`methods/tests/mem_budget.rs`), so it only trades peak RSS for speed. 768 (256 until
/// issue 40): at 10 M terrain points QSplat's, SPT's and MWKD's builds then run in 5, 7 and 1
/// units instead of 15, 23 and 4, ≈ 1 s faster each (QSplat 12.5 → 11.5 s, SPT 18.3 → 17.7
/// s, MWKD 8.5 → 7.4 s; peak RSS 535, 480 and 243 MB); LPC's 50 M build streams two
/// partition passes instead of four and two groups (14.4 → 11.5 s, peak RSS 279 → 749 MB).
/// The memory goal, ≤ 1 GB at 50 M, keeps a margin
/// (`results/measurements/issue-40-builds.md`). potree and voxel keep 256: their units
/// follow PotreeConverter's.
pub const BUILD_MEM_MB: u64 = 768;

/// The most MiB a size parameter (`mem_mb`, `core_mb`, `gpu_limit_mb`) may name: 2³⁰ MiB
/// (1 PiB). Its byte count, `mb · 2²⁰ ≤ 2⁵⁰`, then fits a `u64` with room for the sums and
/// products built from it, where `mb << 20` on a larger value would wrap (2⁴⁴ MiB → 0 bytes).
pub const MAX_MB: u64 = 1 << 30;

/// Checks the size parameter `name` of `method`: `min ≤ mb ≤` [`MAX_MB`], an error naming
/// both otherwise. Every `*_mb` parameter passes through here before its `mb << 20`.
pub fn check_mb(method: &str, name: &str, mb: u64, min: u64) -> Result<(), MethodError> {
    if (min..=MAX_MB).contains(&mb) {
        Ok(())
    } else {
        Err(MethodError::Param(format!(
            "method '{method}': {name} must be in {min}..=2³⁰ (MiB), got {mb}"
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize, PartialEq, Default)]
    #[serde(deny_unknown_fields, default)]
    struct P {
        m: u32,
        kernel: String,
        occlusion: bool,
        scale: f32,
    }

    #[test]
    fn typed_values_and_unknown_keys() {
        let p = Params::parse(&["m=2048", "kernel=circle", "occlusion=true", "scale=0.5"]).unwrap();
        let t: P = p.to_typed("x").unwrap();
        assert_eq!(
            t,
            P {
                m: 2048,
                kernel: "circle".into(),
                occlusion: true,
                scale: 0.5
            }
        );
        let e = Params::parse(&["mm=3"])
            .unwrap()
            .to_typed::<P>("lpc")
            .unwrap_err();
        assert!(e.to_string().contains("unknown field `mm`"), "{e}");
        let e = Params::parse(&["m=-3"])
            .unwrap()
            .to_typed::<P>("lpc")
            .unwrap_err();
        assert!(e.to_string().contains("lpc"), "{e}");
        assert!(Params::parse(&["novalue"]).is_err());
        assert!(Params::parse(&["a=1", "a=2"]).is_err());
    }

    /// Every size parameter of every method is checked before its `mb << 20`: 2⁴⁴ MiB (which
    /// would wrap to 0 bytes) and 2³⁰ + 1 are errors naming the method and the parameter; 2³⁰
    /// itself passes the check. The audit covers each `*_mb` key a method has a default for.
    #[test]
    fn every_size_parameter_is_bounded_before_it_is_shifted() {
        let mut seen = 0;
        for &kind in crate::MethodKind::ALL {
            for key in kind.defaults().into_keys().filter(|k| k.ends_with("_mb")) {
                seen += 1;
                for bad in [1u64 << 44, MAX_MB + 1] {
                    let e = kind
                        .check_params(&Params::parse(&[format!("{key}={bad}")]).unwrap())
                        .expect_err(&format!("{} {key}={bad}", kind.name()))
                        .to_string();
                    assert!(
                        e.contains(kind.name())
                            && e.contains(&format!("{key} must be in"))
                            && e.contains(&format!("got {bad}")),
                        "{e}"
                    );
                }
                kind.check_params(&Params::parse(&[format!("{key}={MAX_MB}")]).unwrap())
                    .unwrap_or_else(|e| panic!("{} {key}=2³⁰: {e}", kind.name()));
            }
        }
        // mem_mb of qsplat, spt, lpc, mwkd, potree, voxel; core_mb of lpc, mwkd, potree,
        // voxel; spt's gpu_limit_mb.
        assert_eq!(seen, 11);
    }
}
