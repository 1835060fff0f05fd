//! `strays=apart` (methods::strays): every method built over the inliers, the far strays
//! drawn beside it. Exact: the inliers' build is the clean cloud's build, sample for sample.
#![allow(clippy::unwrap_used)]

mod common;

use common::{settled, view};
use methods::{LodMethod, MethodError, MethodKind, Params, Target, strays};
use scenes::PointCloud;
use scenes::generators::Generator;

const STRAYS: [[f32; 3]; 2] = [[6.0e6, 1.0e5, -2.0e5], [-3.0e6, 4.0e6, 1.0e5]];

/// The statue, and the statue with [`STRAYS`] appended (normals and colours kept).
fn clouds() -> (PointCloud, PointCloud) {
    let clean = Generator::Statue.generate(20_000, 4).unwrap();
    let (origin, p, n, c, _) = clean.clone().into_columns();
    let p = [p.to_vec(), STRAYS.to_vec()].concat();
    let n = n.map(|n| [n.to_vec(), vec![[0.0, 0.0, 1.0]; 2]].concat());
    let c = c.map(|c| [c.to_vec(), vec![[255, 0, 0]; 2]].concat());
    let stray =
        PointCloud::new(origin, p.into(), n.map(Into::into), c.map(Into::into), None).unwrap();
    (clean, stray)
}

fn build(
    kind: MethodKind,
    cloud: &PointCloud,
    params: &[&str],
    dir: &std::path::Path,
) -> serde_json::Value {
    kind.build(
        cloud,
        &Params::parse(params).unwrap(),
        "test",
        dir,
        &scenes::NoProgress,
    )
    .unwrap();
    serde_json::from_str(&std::fs::read_to_string(dir.join("build.json")).unwrap()).unwrap()
}

fn drawn(m: &mut dyn LodMethod, v: &scenes::View, t: Target) -> u64 {
    let l = settled(m, v, t);
    m.drawn_points(v, &l).unwrap()
}

#[test]
fn every_method_builds_on_the_inliers_and_draws_every_stray() {
    let (clean, stray) = clouds();
    let tmp = tempfile::tempdir().unwrap();
    let v = view(&clean, 2.0);
    for &kind in MethodKind::ALL {
        let (a, b) = (
            tmp.path().join(format!("{kind}-clean")),
            tmp.path().join(format!("{kind}-apart")),
        );
        build(kind, &clean, &[], &a);
        let stats = build(kind, &stray, &["strays=apart"], &b);
        assert_eq!(
            stats["extra"]["strays_apart"], 2,
            "{kind}: build.json counts the strays"
        );
        assert_eq!(stats["points_in"], 20_002, "{kind}");
        let (mut ma, mut mb) = (MethodKind::open(&a).unwrap(), MethodKind::open(&b).unwrap());
        assert_eq!(mb.input_points(), 20_002, "{kind}");
        for t in [
            Target::Tolerance(1.0),
            Target::Tolerance(4.0),
            Target::Budget(10_002),
            // Every sample and both strays: above any root (voxel's, at 20 k samples, is one
            // leaf of them all).
            Target::Budget(20_002),
        ] {
            let own = match t {
                Target::Budget(b) => Target::Budget(b - 2),
                t => t,
            };
            // A budget below a whole-node method's root is refused (tests/contract.rs): by
            // the inliers' build inside just as by the clean build.
            if let Err(e) = ma.frame(&v, own, &Default::default()) {
                let apart = mb.frame(&v, t, &Default::default()).unwrap_err();
                assert!(
                    kind.draws_layers() && e.to_string().contains("smaller than its root"),
                    "{kind} {t:?}: {e}"
                );
                assert_eq!(e.to_string(), apart.to_string(), "{kind} {t:?}");
                continue;
            }
            let (pa, pb) = (drawn(ma.as_mut(), &v, own), drawn(mb.as_mut(), &v, t));
            assert_eq!(
                pb,
                pa + 2,
                "{kind} {t:?}: the clean build's selection plus both strays"
            );
            if let Target::Budget(b) = t {
                assert!(pb <= b, "{kind}: budget {b} exceeded ({pb})");
            }
        }
        let l = settled(mb.as_mut(), &v, Target::Tolerance(1.0));
        let last = l.items.last().unwrap();
        assert!(
            matches!(
                last,
                methods::DrawItem::Chunk {
                    id: strays::CHUNK,
                    points: 2,
                    ..
                }
            ),
            "{kind}: the strays are drawn whole: {last:?}"
        );
        let batch = mb.chunk(strays::CHUNK).unwrap();
        assert_eq!(batch.positions, STRAYS.to_vec(), "{kind}");
        assert_eq!(
            batch.attributes().normals,
            mb.attributes().normals,
            "{kind}"
        );
        assert_eq!(batch.attributes().colors, mb.attributes().colors, "{kind}");
        // The reference's radii: the k-NN radius over the whole cloud, capped as isolated.
        let r = methods::leaf::leaf_radii(&stray);
        assert_eq!(batch.radii.as_deref().unwrap(), &r[20_000..], "{kind}");
        let err = mb
            .frame(&v, Target::Budget(2), &Default::default())
            .unwrap_err();
        assert!(
            matches!(&err, MethodError::Target(m) if m.contains("2 strays") && m.contains("least is 3")),
            "{kind}: {err}"
        );
    }
}

#[test]
fn a_cloud_without_strays_builds_as_the_paper_does() {
    let (clean, _) = clouds();
    let tmp = tempfile::tempdir().unwrap();
    let v = view(&clean, 2.0);
    for kind in [MethodKind::Qsplat, MethodKind::Lpc] {
        let (a, b) = (
            tmp.path().join(format!("{kind}-in")),
            tmp.path().join(format!("{kind}-apart")),
        );
        build(kind, &clean, &[], &a);
        let stats = build(kind, &clean, &["strays=apart"], &b);
        assert_eq!(stats["extra"]["strays_apart"], 0, "{kind}");
        assert!(!b.join(strays::FILE).exists(), "{kind}: no strays file");
        let (mut ma, mut mb) = (MethodKind::open(&a).unwrap(), MethodKind::open(&b).unwrap());
        let t = Target::Tolerance(1.0);
        assert_eq!(
            drawn(ma.as_mut(), &v, t),
            drawn(mb.as_mut(), &v, t),
            "{kind}"
        );
    }
}

#[test]
fn an_unknown_strays_rule_is_an_error_naming_it() {
    let (clean, _) = clouds();
    let tmp = tempfile::tempdir().unwrap();
    for &kind in MethodKind::ALL {
        let p = Params::parse(&["strays=out"]).unwrap();
        let err = kind.check_params(&p).unwrap_err().to_string();
        assert!(
            err.contains("strays=out") && err.contains("apart"),
            "{kind}: {err}"
        );
        let err = kind
            .build(&clean, &p, "test", tmp.path(), &scenes::NoProgress)
            .unwrap_err()
            .to_string();
        assert!(err.contains("strays=out"), "{kind}: {err}");
    }
}

#[test]
fn a_build_that_lost_its_strays_fails_to_open() {
    let (_, stray) = clouds();
    let tmp = tempfile::tempdir().unwrap();
    build(MethodKind::Qsplat, &stray, &["strays=apart"], tmp.path());
    std::fs::remove_file(tmp.path().join(strays::FILE)).unwrap();
    let err = MethodKind::open(tmp.path()).err().unwrap().to_string();
    assert!(err.contains(strays::FILE), "{err}");
}
