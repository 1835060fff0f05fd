//! LPC through `LodMethod` on real builds: budget mode, fetch limits, the stalled loader.
#![allow(clippy::unwrap_used)]

mod common;

use common::{settled, view};
use std::sync::Arc;
use std::time::{Duration, Instant};

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
/// A build of `cloud` by `kind` with `params`, in a temporary directory.
fn built(kind: MethodKind, cloud: &PointCloud, params: &[&str]) -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    kind.build(
        cloud,
        &Params::parse(params).unwrap(),
        "test",
        tmp.path(),
        &scenes::NoProgress,
    )
    .unwrap();
    tmp
}

#[test]
fn figures_disagreeing_with_the_index_are_refused_at_open() {
    let cloud = Generator::Statue.generate(20_000, 2).unwrap();
    for (kind, params, info, samples) in [
        (MethodKind::Lpc, vec!["m=1024"], "lpc.json", false),
        (MethodKind::Mwkd, vec!["vbo=512"], "mwkd.json", true),
    ] {
        let tmp = built(kind, &cloud, &params);
        let path = tmp.path().join(info);
        let mut figures: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let nodes = figures["nodes"].as_u64().unwrap();
        figures["nodes"] = (nodes + 1).into();
        std::fs::write(&path, figures.to_string()).unwrap();
        let e = MethodKind::open(tmp.path()).err().unwrap();
        assert!(matches!(e, methods::MethodError::Corrupt { .. }), "{e}");
        let e = e.to_string();
        assert!(
            e.contains(info)
                && e.contains(&format!(
                    "{} nodes / 20000 points disagree with the index ({nodes} nodes",
                    nodes + 1
                ))
                && e.contains(", 20000 samples") == samples
                && e.contains("and the manifest (20000 points)"),
            "{e}"
        );
    }
}

#[test]
fn budget_below_the_root_is_an_error_naming_the_least() {
    let cloud = Generator::Statue.generate(20_000, 2).unwrap();
    for (kind, params, root) in [
        (MethodKind::Lpc, vec!["m=1024"], 1024u64),
        (MethodKind::Mwkd, vec!["vbo=512"], 512),
    ] {
        let tmp = built(kind, &cloud, &params);
        let mut m = MethodKind::open(tmp.path()).unwrap();
        let v = view(&cloud, 3.0);
        for b in [1, root - 1] {
            let e = m
                .frame(&v, Target::Budget(b), &Feedback::default())
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(&format!("a budget of {b} points is smaller than"))
                    && e.contains(&format!("give a budget of {root} or more")),
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

/// A data-access layer that delegates to LPC's own loader but reports a fixed throughput,
/// so that the request count of a frame can be checked against the paper's rule.
struct FixedRate {
    inner: Box<dyn methods::store::access::DataAccess>,
    chunks_per_s: Option<f64>,
}

impl methods::store::access::DataAccess for FixedRate {
    fn request(&self, id: u32) {
        self.inner.request(id)
    }
    fn available(&self, id: u32) -> bool {
        self.inner.available(id)
    }
    fn get(&self, id: u32) -> Result<methods::store::access::Decoded, methods::MethodError> {
        self.inner.get(id)
    }
    fn begin_frame(&self) {
        self.inner.begin_frame()
    }
    fn resident_bytes(&self) -> u64 {
        self.inner.resident_bytes()
    }
    fn pending(&self) -> usize {
        self.inner.pending()
    }
    fn throughput(&self) -> Option<methods::store::access::Throughput> {
        self.chunks_per_s
            .map(|c| methods::store::access::Throughput {
                bytes_per_s: c * 1000.0,
                chunks_per_s: c,
                responses: 1,
            })
    }
}

/// LPC over [`FixedRate`] with `runtime` parameters on the build in `dir`.
fn lpc_at_rate(dir: &std::path::Path, runtime: &[&str], rate: Option<f64>) -> methods::lpc::Lpc {
    use methods::store::access::{Loader, LoaderOptions};
    let mut manifest = methods::Manifest::read(dir).unwrap();
    for p in runtime {
        let (k, v) = p.split_once('=').unwrap();
        manifest.params.0.insert(k.into(), v.into());
    }
    let nodes = methods::lpc::index::read(&dir.join(methods::lpc::INDEX_FILE)).unwrap();
    let inner = Loader::local(
        &dir.join(methods::lpc::REPO_FILE),
        nodes.iter().map(|n| n.chunk).collect(),
        "cloud",
        Arc::new(methods::lpc::cloud::decode),
        LoaderOptions {
            core_bytes: 64 << 20,
            delay_frames: 0,
            in_flight: 1,
        },
    )
    .unwrap();
    let access = FixedRate {
        inner: Box::new(inner),
        chunks_per_s: rate,
    };
    methods::lpc::Lpc::with_access(dir, manifest, nodes, Box::new(access)).unwrap()
}

/// The paper's rule, "only as many requests as the estimated bandwidth allows": chunks/s ×
/// the last frame's duration, rounded up. Before any frame interval, or with no estimate,
/// and with a simulated latency, the fixed [`methods::lpc::UNMEASURED_FETCH_PER_FRAME`];
/// `fetch_per_frame` overrides the rule.
#[test]
fn requests_per_frame_follow_the_measured_rate() {
    let cloud = Generator::Statue.generate(40_000, 6).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    open(&cloud, &["m=128"], tmp.path());
    let v = view(&cloud, 1.2);
    let t = Target::Tolerance(0.5);
    let issued = |l: &methods::DrawList| l.counters[2] as usize;
    let rate = 400.0;
    let nap = Duration::from_millis(50);

    let unmeasured = methods::lpc::UNMEASURED_FETCH_PER_FRAME as usize;

    // No estimate: the fixed count every frame, seen where a frame wants more (a coarse
    // tolerance settled first, the fine one then wants a whole frontier of clouds).
    let mut m = lpc_at_rate(tmp.path(), &[], None);
    common::settled(&mut m, &v, Target::Tolerance(4.0));
    let l = m.frame(&v, t, &Feedback::default()).unwrap();
    assert!(l.fetch.len() > unmeasured, "{} wanted", l.fetch.len());
    assert_eq!(issued(&l), unmeasured);

    // 400 chunks/s and a frame of ≥ 50 ms: ⌈400 × dt⌉ requests, dt bounded by the clock.
    // The first frame has no interval yet: the fixed count (its view wants the root's
    // children only).
    let mut m = lpc_at_rate(tmp.path(), &[], Some(rate));
    let first = m.frame(&v, t, &Feedback::default()).unwrap();
    assert_eq!(issued(&first), unmeasured.min(first.fetch.len()));
    common::settled(&mut m, &v, Target::Tolerance(4.0));
    let before = Instant::now();
    m.frame(&v, t, &Feedback::default()).unwrap();
    std::thread::sleep(nap);
    let second = m.frame(&v, t, &Feedback::default()).unwrap();
    let longest = before.elapsed().as_secs_f64();
    let wanted = second.fetch.len();
    assert!(
        wanted > 40,
        "the view wants {wanted} clouds: too few to see the limit"
    );
    let n = issued(&second);
    assert!(
        n >= (rate * nap.as_secs_f64()).ceil() as usize && n <= (rate * longest).ceil() as usize,
        "{n} requests at {rate} chunks/s over a frame of 50–{:.0} ms",
        longest * 1e3
    );
    assert_eq!(
        n + second.counters[3] as usize,
        wanted,
        "the rest are forgotten"
    );

    // The override, and the simulated latency's fixed count.
    for (runtime, want) in [
        (&["fetch_per_frame=5"][..], 5),
        (&["delay_frames=1"][..], unmeasured),
    ] {
        let mut m = lpc_at_rate(tmp.path(), runtime, Some(rate));
        m.frame(&v, t, &Feedback::default()).unwrap();
        std::thread::sleep(nap);
        let l = m.frame(&v, t, &Feedback::default()).unwrap();
        assert_eq!(issued(&l), want.min(l.fetch.len()), "{runtime:?}");
    }
}

/// An index without nodes given to `with_access` is a corrupt build named as such, never a
/// panic (it read the root's sample count from `nodes[0]`).
#[test]
fn an_empty_index_is_refused_by_with_access() {
    use methods::store::access::{Loader, LoaderOptions};
    let cloud = Generator::Statue.generate(20_000, 2).unwrap();
    let tmp = built(MethodKind::Mwkd, &cloud, &["vbo=512"]);
    let dir = tmp.path();
    let manifest = methods::Manifest::read(dir).unwrap();
    let nodes = methods::mwkd::index::read(&dir.join(methods::mwkd::INDEX_FILE)).unwrap();
    let access = Loader::local(
        &dir.join(methods::mwkd::codec::REPO_FILE),
        nodes.iter().map(|n| n.chunk).collect(),
        "node",
        Arc::new(methods::mwkd::codec::decode),
        LoaderOptions {
            core_bytes: 64 << 20,
            delay_frames: 0,
            in_flight: 1,
        },
    )
    .unwrap();
    let e = methods::mwkd::Mwkd::with_access(dir, manifest, Vec::new(), Box::new(access))
        .err()
        .unwrap();
    assert!(matches!(e, methods::MethodError::Corrupt { .. }), "{e}");
    assert!(e.to_string().contains("no nodes"), "{e}");
}
