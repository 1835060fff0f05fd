//! Unit tests of `spec.rs`.
use super::*;

#[test]
fn parses_generators_and_files() {
    let s = SceneSpec::parse("statue:200k", None, 9).unwrap();
    assert_eq!(
        s.source,
        SceneSource::Generator {
            generator: Generator::Statue,
            points: 200_000,
            seed: 9,
            sampling: Sampling::Even,
        }
    );
    assert_eq!(s.label(), "statue:200000:9");
    // Even is the statue's default: naming it changes nothing.
    let even = SceneSpec::parse("statue:200k:9:even", None, 1).unwrap();
    assert_eq!(even.source, s.source);
    assert_eq!(even.label(), "statue:200000:9");
    assert_eq!(even.content_hash().unwrap(), s.content_hash().unwrap());
    let random = SceneSpec::parse("statue:200k:9:random", None, 1).unwrap();
    assert!(matches!(
        random.source,
        SceneSource::Generator {
            sampling: Sampling::Random,
            seed: 9,
            ..
        }
    ));
    assert_eq!(random.label(), "statue:200000:9:random");
    assert_ne!(random.content_hash().unwrap(), s.content_hash().unwrap());
    // Terrain stays random by default (aerial LiDAR).
    let t = SceneSpec::parse("terrain:1000:2", None, 1).unwrap();
    assert_eq!(t.label(), "terrain:1000:2");
    assert_eq!(
        SceneSpec::parse("terrain:1000:2:even", None, 1)
            .unwrap()
            .label(),
        "terrain:1000:2:even"
    );
    let s = SceneSpec::parse("terrain:10M:3", None, 9).unwrap();
    assert!(matches!(
        s.source,
        SceneSource::Generator {
            points: 10_000_000,
            seed: 3,
            ..
        }
    ));
    assert!(matches!(
        SceneSpec::parse("a/b.PLY", Some(5), 1).unwrap().source,
        SceneSource::Ply {
            sample: Some(5),
            ..
        }
    ));
    assert!(matches!(
        SceneSpec::parse("x.laz", None, 1).unwrap().source,
        SceneSource::Las { .. }
    ));
}

#[test]
fn rejects_bad_specs() {
    for (spec, needle) in [
        ("bunny", "known: statue"),
        ("statue", "missing point count"),
        ("statue:0", "at least 1"),
        ("statue:abc", "not a point count"),
        ("statue:10:x", "seed 'x'"),
        ("statue:10:1:2", "sampling '2'"),
        ("statue:10:1:even:x", "too many"),
    ] {
        let e = SceneSpec::parse(spec, None, 1).unwrap_err().to_string();
        assert!(e.contains(needle), "{spec}: {e}");
    }
    let e = SceneSpec::parse("statue:10", Some(3), 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--sample"), "{e}");
}

#[test]
fn scene_toml_rejects_unknown_keys() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("s.toml");
    std::fs::write(&p, "generator = \"statue\"\npoints = 1000\nsed = 3\n").unwrap();
    let e = SceneSpec::parse(p.to_str().unwrap(), None, 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("sed") && e.contains("s.toml"), "{e}");
    std::fs::write(&p, "generator = \"statue\"\npoints = 1000\nseed = 3\n").unwrap();
    let s = SceneSpec::parse(p.to_str().unwrap(), None, 1).unwrap();
    assert_eq!(s.label(), "statue:1000:3");
    std::fs::write(
        &p,
        "generator = \"statue\"\npoints = 1000\nsampling = \"even\"\n",
    )
    .unwrap();
    let s = SceneSpec::parse(p.to_str().unwrap(), None, 1).unwrap();
    assert_eq!(s.label(), "statue:1000:1");
    std::fs::write(
        &p,
        "generator = \"statue\"\npoints = 1000\nsampling = \"random\"\n",
    )
    .unwrap();
    let s = SceneSpec::parse(p.to_str().unwrap(), None, 1).unwrap();
    assert_eq!(s.label(), "statue:1000:1:random");
    std::fs::write(
        &p,
        "generator = \"statue\"\npoints = 1000\nsampling = \"odd\"\n",
    )
    .unwrap();
    let e = SceneSpec::parse(p.to_str().unwrap(), None, 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("sampling 'odd'") && e.contains("s.toml"), "{e}");
    std::fs::write(&p, "file = \"x.ply\"\nsampling = \"even\"\n").unwrap();
    let e = SceneSpec::parse(p.to_str().unwrap(), None, 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("`sampling` applies to generators"), "{e}");
    std::fs::write(&p, "file = \"x.ply\"\ngenerator = \"statue\"\n").unwrap();
    let e = SceneSpec::parse(p.to_str().unwrap(), None, 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("exactly one"), "{e}");
}
