//! Helpers shared by the method integration tests (`mod common;` in each test file).
#![allow(dead_code, clippy::unwrap_used)]

use glam::Vec3;
use methods::{DrawList, Feedback, LodMethod, Target};
use scenes::generators::Generator;
use scenes::paths::PathSpec;
use scenes::{Camera, PointCloud, View};

/// A 320 × 240 view of `cloud` from `dist` bounding radii away, looking at its centre.
pub fn view(cloud: &PointCloud, dist: f32) -> View {
    let b = cloud.bounds();
    let c = b.center();
    View {
        camera: Camera {
            position: c + Vec3::new(0.3, -1.0, 0.4).normalize() * b.radius() * dist,
            target: c,
            up: Vec3::Z,
            fov_y: 0.8,
            near: b.radius() * 0.01,
            far: b.radius() * 100.0,
        },
        width: 320,
        height: 240,
    }
}

/// Repeats the frame (as a still camera would) until nothing is missing; panics after 5000.
pub fn settled(m: &mut dyn LodMethod, v: &View, t: Target) -> DrawList {
    settled_with(m, v, t, &Feedback::default())
}

/// [`settled`] with the given feedback every frame.
pub fn settled_with(m: &mut dyn LodMethod, v: &View, t: Target, fb: &Feedback) -> DrawList {
    for _ in 0..5000 {
        let l = m.frame(v, t, fb).unwrap();
        if l.fetch.is_empty() {
            return l;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    panic!("never settled");
}

/// A statue with the degenerate cases of the leaf radii: 7 exact copies of 30 samples (their
/// 6th neighbour is at distance 0: the fallback) and 6 far strays (capped as isolated); with
/// varied colours when `colors` (the statue has none), so that the colour rules take part.
pub fn degenerate_statue(colors: bool) -> PointCloud {
    let c = scenes::generators::Generator::Statue
        .generate(9_000, 4)
        .unwrap();
    let mut pos = c.positions().to_vec();
    let mut nrm = c.normals().unwrap().to_vec();
    let mut col: Vec<[u8; 3]> = (0..c.len())
        .map(|i| [(i % 251) as u8, 90, (i % 7) as u8 * 30])
        .collect();
    for i in 0..30 {
        for _ in 0..7 {
            pos.push(pos[i * 200]);
            nrm.push(nrm[i * 200]);
            col.push(col[i * 200]);
        }
    }
    for j in 0..6 {
        pos.push([40.0 + 9.0 * j as f32, -30.0, 25.0 * j as f32]);
        nrm.push([0.0, 0.0, 1.0]);
        col.push([255, 0, 0]);
    }
    let col = colors.then(|| col.into());
    PointCloud::new(c.origin(), pos.into(), Some(nrm.into()), col, None).unwrap()
}

/// A build in units that calls a hook with its spill files.
pub type HookedBuild<'a> = &'a dyn Fn(
    &std::path::Path,
    &dyn Fn(&[&methods::spill::Spill]),
) -> Result<(), methods::MethodError>;

/// Damages one spill file of `build` (into `out/<case>`) in each of three ways — cut short,
/// a flipped bit, removed — and checks that each is an error naming the file and saying
/// what is wrong, and that nothing is left in the output directory.
pub fn spill_damage_is_named(out: &std::path::Path, build: HookedBuild<'_>) {
    let named = std::cell::RefCell::new(String::new());
    type Damage = fn(&std::path::Path);
    let cases: [(&str, Damage); 3] = [
        ("holds", |p| {
            let b = std::fs::read(p).unwrap();
            std::fs::write(p, &b[..b.len() - 3]).unwrap();
        }),
        ("checksum mismatch", |p| {
            let mut b = std::fs::read(p).unwrap();
            b[20] ^= 4;
            std::fs::write(p, &b).unwrap();
        }),
        ("No such file", |p| std::fs::remove_file(p).unwrap()),
    ];
    for (what, damage) in cases {
        let dir = out.join(what);
        std::fs::create_dir_all(&dir).unwrap();
        let hook = |spills: &[&methods::spill::Spill]| {
            assert!(spills.len() >= 5, "{} units", spills.len());
            let victim = &spills[spills.len() / 2].path;
            *named.borrow_mut() = victim.display().to_string();
            damage(victim);
        };
        let err = build(&dir, &hook).unwrap_err().to_string();
        assert!(
            err.contains(named.borrow().as_str()) && err.contains(what),
            "{what}: {err}"
        );
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert!(left.is_empty(), "{what}: left {left:?}");
    }
}

/// Runs `f` on a rayon pool of `threads` threads.
pub fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// The names of the entries of `dir`, sorted.
pub fn entries(dir: &std::path::Path) -> Vec<String> {
    let mut e: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    e.sort();
    e
}

/// Builds an SPT of `cloud` with `params` into `dir` and opens it.
pub fn spt_build_open(
    cloud: &PointCloud,
    params: &[&str],
    dir: &std::path::Path,
) -> Result<methods::spt::Spt, methods::MethodError> {
    std::fs::create_dir_all(dir).unwrap();
    methods::spt::build(
        cloud,
        &methods::Params::parse(params).unwrap(),
        "test",
        dir,
        &scenes::NoProgress,
    )?;
    methods::spt::Spt::open(dir, methods::Manifest::read(dir).unwrap())
}

/// A node of a build in the Potree format (`potree`, `voxel`) read back: its span, and its
/// records' integer positions and 8-bit colours.
pub type NodeRecords = (
    methods::potree::hierarchy::Span,
    Vec<([i32; 3], Option<[u8; 3]>)>,
);

/// Every record of the build in the Potree format in `dir` (its info file `info`, read with
/// `mode`), node by node in the hierarchy's order, with the metadata.
pub fn read_back(
    dir: &std::path::Path,
    info: &str,
    mode: methods::potree::Mode,
) -> (methods::potree::format::Metadata, Vec<NodeRecords>) {
    use glam::DVec3;
    use methods::potree::format::{Decoding, Metadata};
    let meta = Metadata::read(dir).unwrap();
    let layout = meta.layout(&dir.join("metadata.json")).unwrap();
    let dec = Decoding {
        layout,
        scale: DVec3::from(meta.scale),
        offset: DVec3::from(meta.offset),
        origin: DVec3::ZERO,
    };
    let info: methods::potree::Info =
        serde_json::from_str(&std::fs::read_to_string(dir.join(info)).unwrap()).unwrap();
    let params = methods::potree::PotreeParams::default();
    let mut p =
        methods::potree::Potree::open_as(dir, DVec3::from(info.origin), &params, mode).unwrap();
    p.expand_all().unwrap();
    let octree = std::fs::read(dir.join("octree.bin")).unwrap();
    let spans = p.hierarchy().spans();
    let spans = spans.read().unwrap();
    let nodes = spans
        .iter()
        .map(|s| {
            let bytes = &octree[s.offset as usize..(s.offset + s.size) as usize];
            let recs = (0..s.points as usize)
                .map(|i| (dec.raw_position(bytes, i), dec.color(bytes, i)))
                .collect();
            (*s, recs)
        })
        .collect();
    (meta, nodes)
}

/// The statue SPT's tests use (seed 7).
pub fn spt_statue(n: usize) -> PointCloud {
    Generator::Statue.generate(n, 7).unwrap()
}

/// Four orbit and three zoom views at 640 × 480, SPT's tests' views.
pub fn spt_views(cloud: &PointCloud) -> Vec<View> {
    let b = cloud.bounds();
    let mut v: Vec<View> = (0..4)
        .map(|i| View {
            camera: PathSpec::parse("orbit").unwrap().camera(i, 4, &b),
            width: 640,
            height: 480,
        })
        .collect();
    for i in [3, 7, 9] {
        v.push(View {
            camera: PathSpec::parse("zoom").unwrap().camera(i, 10, &b),
            width: 640,
            height: 480,
        });
    }
    v
}
