//! LPC through `LodMethod` on real builds: budget mode, fetch limits, the stalled loader.
#![allow(clippy::unwrap_used)]

mod common;

use common::{settled, view};
use methods::{Feedback, LodMethod, MethodKind, Params, Target};
use scenes::PointCloud;
use scenes::generators::Generator;

fn open(cloud: &PointCloud, params: &[&str], dir: &std::path::Path) -> Box<dyn LodMethod> {
    let p = Params::parse(params).unwrap();
    MethodKind::Lpc
        .build(cloud, &p, "test", dir, &scenes::NoProgress)
        .unwrap();
    MethodKind::open(dir).unwrap()
}

#[test]
fn budget_is_never_exceeded_and_within_one_cloud() {
    let cloud = Generator::Statue.generate(60_000, 5).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let m_cloud = 1024u64;
    let mut m = open(&cloud, &["m=1024"], tmp.path());
    for dist in [1.2f32, 2.5, 6.0] {
        let v = view(&cloud, dist);
        let all = settled(m.as_mut(), &v, Target::Tolerance(0.0)).points();
        for b in [1_500u64, 4_000, 9_999, 20_000, 33_333, all] {
            let l = settled(m.as_mut(), &v, Target::Budget(b));
            let p = l.points();
            assert!(p <= b, "view {dist}: budget {b} exceeded: {p}");
            assert!(
                b - p < m_cloud || p == all,
                "view {dist}: budget {b} drew {p}: more than one cloud short (all = {all})"
            );
        }
    }
}

#[test]
fn at_most_fetch_per_frame_requests_and_progressive_refinement() {
    let cloud = Generator::Statue.generate(40_000, 6).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let mut m = open(&cloud, &["m=256", "fetch_per_frame=3"], tmp.path());
    let cols = m.extra_columns().to_vec();
    let issued = cols.iter().position(|c| *c == "fetch_issued").unwrap();
    let dropped = cols.iter().position(|c| *c == "fetch_dropped").unwrap();
    let v = view(&cloud, 1.5);
    let mut last = 0;
    let mut frames = 0;
    loop {
        let l = m
            .frame(&v, Target::Tolerance(1.0), &Feedback::default())
            .unwrap();
        assert!(l.counters[issued] <= 3.0);
        assert_eq!(
            l.counters[issued] + l.counters[dropped],
            l.fetch.len() as f64,
            "every wanted cloud is issued or forgotten"
        );
        assert!(l.points() >= last, "a still camera never gets coarser");
        last = l.points();
        frames += 1;
        if l.fetch.is_empty() {
            break;
        }
        assert!(frames < 2000);
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    assert!(
        frames > 3,
        "refinement took {frames} frames with 3 requests per frame"
    );
}

/// A budget below the root cloud (issue 13, item 6) is refused with the smallest budget that
/// draws, for LPC and MWKD alike, instead of an empty frame; the root's size itself draws.
#[test]
fn budget_below_the_root_is_an_error_naming_the_least() {
    let cloud = Generator::Statue.generate(20_000, 2).unwrap();
    for (kind, params, root) in [
        (MethodKind::Lpc, vec!["m=1024"], 1024u64),
        (MethodKind::Mwkd, vec!["vbo=512"], 512),
    ] {
        let tmp = tempfile::tempdir().unwrap();
        kind.build(
            &cloud,
            &Params::parse(&params).unwrap(),
            "test",
            tmp.path(),
            &scenes::NoProgress,
        )
        .unwrap();
        let mut m = MethodKind::open(tmp.path()).unwrap();
        let v = view(&cloud, 3.0);
        for b in [1, root - 1] {
            let e = m
                .frame(&v, Target::Budget(b), &Feedback::default())
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(&format!("--budget {b} is smaller than"))
                    && e.contains(&format!("give --budget {root} or more")),
                "{kind}: {e}"
            );
        }
        let l = settled(m.as_mut(), &v, Target::Budget(root));
        assert!(
            l.points() > 0 && l.points() <= root,
            "{kind}: {}",
            l.points()
        );
    }
}
