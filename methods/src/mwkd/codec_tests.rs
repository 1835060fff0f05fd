//! Unit tests of `codec.rs`.
#![allow(clippy::unwrap_used)]
use super::*;
use crate::store::chunk_header::FLAG_NORMALS;
use scenes::rng::Pcg32;

/// Angle between two vectors (atan2 of |a×b| and a·b: exact for small angles).
fn angle(a: Vec3, b: Vec3) -> f32 {
    a.cross(b).length().atan2(a.dot(b))
}

struct Node {
    points: Vec<[f32; 3]>,
    radii: Vec<f32>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[u8; 3]>,
}

fn random_node(n: usize, seed: u64) -> Node {
    let mut rng = Pcg32::new(seed);
    Node {
        points: (0..n)
            .map(|_| {
                [
                    rng.range_f32(-3.0, 5.0),
                    rng.range_f32(0.0, 1e-3),
                    rng.range_f32(100.0, 101.5),
                ]
            })
            .collect(),
        radii: (0..n).map(|_| rng.range_f32(0.001, 0.05)).collect(),
        normals: (0..n)
            .map(|_| (rng.unit_vec3() * rng.range_f32(0.1, 10.0)).to_array())
            .collect(),
        colors: (0..n)
            .map(|_| [0, 1, 2].map(|_| rng.below(256) as u8))
            .collect(),
    }
}

fn ulp(x: f32) -> f32 {
    x.abs().next_up() - x.abs()
}

/// Encodes `node` with every combination of optional columns, decodes, and checks every
/// bound of the module documentation and the exact size.
fn check_round_trip(node: &Node) {
    let n = node.points.len();
    for (with_n, with_c) in [(false, false), (true, false), (false, true), (true, true)] {
        let (bytes, h) = encode(
            &node.points,
            &node.radii,
            with_n.then_some(&node.normals[..]),
            with_c.then_some(&node.colors[..]),
        )
        .unwrap();
        let per_point = 6 + 1 + if with_n { 2 } else { 0 } + if with_c { 3 } else { 0 };
        assert_eq!(bytes.len(), HEADER_BYTES + n * per_point);
        assert_eq!(NodeHeader::parse(7, &bytes).unwrap(), h);
        let b = decode(7, &bytes).unwrap();
        b.validate().unwrap();
        assert_eq!(b.len(), n);
        for a in 0..3 {
            let e = h.max[a] as f64 - h.min[a] as f64;
            let tol = (e / 65_535.0 / 2.0) as f32 + ulp(h.min[a]).max(ulp(h.max[a]));
            for (p, d) in node.points.iter().zip(&b.positions) {
                assert!(
                    (p[a] - d[a]).abs() <= tol,
                    "axis {a}: {p:?} → {d:?}, tol {tol}"
                );
                assert!(h.min[a] <= d[a] && d[a] <= h.max[a]);
                if e == 0.0 {
                    assert_eq!(d[a], p[a]);
                }
            }
        }
        let radii = b.radii.as_ref().unwrap();
        let step = (h.radius_max - h.radius_min) / 255.0;
        for (r, d) in node.radii.iter().zip(radii) {
            assert!(d >= r, "radius {r} decoded smaller: {d}");
            assert!(
                d - r <= step + ulp(h.radius_max),
                "radius {r} → {d}, step {step}"
            );
        }
        if h.radius_min == h.radius_max {
            assert!(radii.iter().all(|&d| d == h.radius_min));
        }
        assert_eq!(b.normals.is_some(), with_n);
        if let Some(nrm) = &b.normals {
            for (v, &p) in node.normals.iter().zip(nrm) {
                let a = angle(Vec3::from(*v), octnormal::decode(p));
                assert!(a <= MAX_NORMAL_ERROR_RAD, "{v:?}: {a} rad");
            }
        }
        assert_eq!(b.colors.is_some(), with_c);
        if let Some(col) = &b.colors {
            for (c, &p) in node.colors.iter().zip(col) {
                assert_eq!(pack_color(*c), p);
            }
        }
    }
}

#[test]
fn round_trip_random_within_bounds() {
    check_round_trip(&random_node(5000, 11));
    check_round_trip(&random_node(37, 12));
}

#[test]
fn round_trip_degenerate_nodes() {
    // One point.
    check_round_trip(&random_node(1, 21));
    // All points identical (zero extent on every axis, equal radii).
    let mut node = random_node(64, 22);
    let (p, r, nv, c) = (
        node.points[0],
        node.radii[0],
        node.normals[0],
        node.colors[0],
    );
    node.points.fill(p);
    node.radii.fill(r);
    node.normals.fill(nv);
    node.colors.fill(c);
    check_round_trip(&node);
    // Zero-extent axis, equal radii, zero radii, axis-aligned and tie normals.
    let mut node = random_node(300, 23);
    node.points.iter_mut().for_each(|p| p[1] = -7.25);
    node.radii.fill(0.03);
    check_round_trip(&node);
    node.radii.fill(0.0);
    let specials = [
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        [1.0, 1.0, 1.0],
        [-1.0, 1.0, -1.0],
        [1.0, -1.0, 0.0],
        [1e-30, 0.0, -1e-30],
    ];
    for (v, s) in node.normals.iter_mut().zip(specials) {
        *v = s;
    }
    check_round_trip(&node);
    // Large coordinates and a huge radius range.
    let mut node = random_node(200, 24);
    node.points.iter_mut().for_each(|p| p[0] = p[0] * 1e6 + 3e7);
    node.radii[0] = 1e6;
    node.radii[1] = 0.0;
    check_round_trip(&node);
}

#[test]
fn radius_is_never_smaller_and_at_most_one_step_larger() {
    let mut rng = Pcg32::new(31);
    for (lo, hi) in [
        (0.01f32, 0.05f32),
        (1.0, 1.0f32.next_up().next_up().next_up()),
        (0.0, 1e-30),
        (3.0, 3.000_01),
        (0.0, 1e30),
        (12.5, 12.5),
    ] {
        let step = (hi - lo) / 255.0;
        let mut rs: Vec<f32> = (0..20_000).map(|_| rng.range_f32(lo, hi)).collect();
        // Exactly on and next to every code's value.
        for q in 0..=255u8 {
            let v = dequantise_radius(q, lo, hi);
            rs.extend([v, v.next_up(), v.next_down()]);
        }
        for r in rs.into_iter().map(|r| r.clamp(lo, hi)) {
            let d = dequantise_radius(quantise_radius(r, lo, hi), lo, hi);
            assert!(d >= r, "[{lo}, {hi}]: {r} → {d}");
            assert!(d - r <= step + ulp(hi), "[{lo}, {hi}]: {r} → {d}");
        }
    }
}

#[test]
fn octahedral_table_is_the_decoded_code_of_every_code() {
    let t = octahedral_table();
    assert_eq!(t.len(), NORMAL_CODES as usize);
    for c in 0..NORMAL_CODES {
        let v = decode_normal(c as u16).unwrap();
        assert_eq!(t[c as usize], octnormal::encode(v), "code {c}");
    }
    assert!(decode_normal(NORMAL_CODES as u16).is_none());
}

#[test]
fn normal_cube_map_bound() {
    // The farthest point of a cell from its centre is a corner (the angle to the centre
    // is quasi-convex on the face plane): check every corner of every cell of every face.
    let g = NORMAL_GRID as f32;
    let corner = |i: u32| i as f32 / g * 2.0 - 1.0;
    let mut worst = 0f32;
    for code in 0..NORMAL_CODES as u16 {
        let c = decode_normal(code).unwrap();
        let face = code as u32 / (NORMAL_GRID * NORMAL_GRID);
        let cell = code as u32 % (NORMAL_GRID * NORMAL_GRID);
        let (row, col) = (cell / NORMAL_GRID, cell % NORMAL_GRID);
        let a = (face / 2) as usize;
        for (dr, dc) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let mut v = [0f32; 3];
            v[a] = if face.is_multiple_of(2) { 1.0 } else { -1.0 };
            v[(a + 1) % 3] = corner(row + dr);
            v[(a + 2) % 3] = corner(col + dc);
            worst = worst.max(angle(Vec3::from(v), c));
        }
        // The centre encodes to its own code.
        assert_eq!(encode_normal(c.to_array()), Some(code));
    }
    let cube_bound = (2f32.sqrt() / g).atan();
    assert!(worst <= cube_bound + 1e-6, "worst {worst} vs {cube_bound}");
    assert!(
        worst > cube_bound - 1e-4,
        "the stated bound is tight: {worst}"
    );
    assert!(cube_bound + 5e-5 <= MAX_NORMAL_ERROR_RAD);
    // Random directions through the whole path to the renderer's packing.
    let mut rng = Pcg32::new(41);
    let mut worst = 0f32;
    for _ in 0..200_000 {
        let v = rng.unit_vec3();
        let code = encode_normal(v.to_array()).unwrap();
        assert!((code as u32) < NORMAL_CODES);
        let d = octnormal::decode(octnormal::encode(decode_normal(code).unwrap()));
        worst = worst.max(angle(v, d));
    }
    assert!(worst <= MAX_NORMAL_ERROR_RAD, "worst {worst} rad");
    assert!(decode_normal(NORMAL_CODES as u16).is_none());
    assert!(decode_normal(u16::MAX).is_none());
    assert_eq!(encode_normal([0.0; 3]), None);
    assert_eq!(encode_normal([f32::NAN, 1.0, 0.0]), None);
}

#[test]
fn encode_rejects_bad_input() {
    let node = random_node(10, 51);
    let (p, r) = (&node.points[..], &node.radii[..]);
    let cases: Vec<(Result<_, _>, &str)> = vec![
        (encode(&[], &[], None, None), "0 points"),
        (encode(p, &r[..9], None, None), "9 radii"),
        (encode(p, r, Some(&node.normals[..3]), None), "3 normals"),
        (encode(p, r, None, Some(&node.colors[..2])), "2 colors"),
        (
            encode(&[[f32::NAN, 0.0, 0.0]], &[1.0], None, None),
            "point 0",
        ),
        (encode(&[[0.0; 3]], &[-1.0], None, None), "radius 0"),
        (
            encode(&[[0.0; 3]], &[f32::INFINITY], None, None),
            "radius 0",
        ),
        (
            encode(&[[0.0; 3]], &[1.0], Some(&[[0.0; 3]]), None),
            "normal 0",
        ),
    ];
    for (res, needle) in cases {
        let e = res.unwrap_err().to_string();
        assert!(e.contains(needle), "{needle}: {e}");
    }
}

fn set_f32(bytes: &mut [u8], at: usize, v: f32) {
    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

#[test]
fn corruption_is_an_error_naming_the_node() {
    let node = random_node(120, 61);
    let (bytes, h) = encode(
        &node.points,
        &node.radii,
        Some(&node.normals),
        Some(&node.colors),
    )
    .unwrap();
    let is_corrupt = |b: &[u8], needle: &str| {
        let e = decode(9, b).unwrap_err();
        assert!(matches!(e, MethodError::Corrupt { .. }), "{e}");
        let s = e.to_string();
        assert!(s.contains("node 9") && s.contains(needle), "{needle}: {s}");
    };
    for cut in [
        0,
        3,
        HEADER_BYTES - 1,
        HEADER_BYTES,
        HEADER_BYTES + 7,
        bytes.len() - 1,
    ] {
        is_corrupt(&bytes[..cut], "bytes");
    }
    let mut long = bytes.clone();
    long.push(0);
    is_corrupt(&long, "need");
    let edit = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = bytes.clone();
        f(&mut b);
        b
    };
    is_corrupt(&edit(&|b| b[0] = b'X'), "magic");
    is_corrupt(&edit(&|b| b[2] = 2), "version");
    is_corrupt(&edit(&|b| b[3] |= 4), "flags");
    is_corrupt(&edit(&|b| b[3] = FLAG_NORMALS), "need");
    is_corrupt(
        &edit(&|b| b[4..8].copy_from_slice(&0u32.to_le_bytes())),
        "count 0",
    );
    is_corrupt(
        &edit(&|b| b[4..8].copy_from_slice(&121u32.to_le_bytes())),
        "need",
    );
    is_corrupt(
        &edit(&|b| b[4..8].copy_from_slice(&u32::MAX.to_le_bytes())),
        "need",
    );
    is_corrupt(&edit(&|b| set_f32(b, 12, f32::NAN)), "axis 1");
    is_corrupt(&edit(&|b| set_f32(b, 20, f32::INFINITY)), "axis 0");
    is_corrupt(&edit(&|b| set_f32(b, 28, h.min[2] - 1.0)), "axis 2");
    is_corrupt(&edit(&|b| set_f32(b, 32, h.radius_max * 2.0)), "radius");
    is_corrupt(&edit(&|b| set_f32(b, 32, -0.5)), "radius");
    is_corrupt(&edit(&|b| set_f32(b, 36, f32::NAN)), "radius");
    let n = node.points.len();
    let nrm = HEADER_BYTES + 7 * n;
    // Point 5's normal code: high byte plane then low byte plane.
    is_corrupt(
        &edit(&|b| (b[nrm + 5], b[nrm + n + 5]) = (0xfd, 0x80)),
        "64896",
    );
    is_corrupt(
        &edit(&|b| (b[nrm + 5], b[nrm + n + 5]) = (0xff, 0xff)),
        "point 5",
    );
    assert!(decode(9, &edit(&|b| (b[nrm + 5], b[nrm + n + 5]) = (0xfd, 0x7f))).is_ok());
    // Every single flipped byte (three patterns): a `Corrupt` error naming the node, or a
    // batch inside the box and radius range its (possibly altered) header declares.
    for i in 0..bytes.len() {
        for x in [0x01u8, 0x80, 0xa5] {
            let mut b = bytes.clone();
            b[i] ^= x;
            match decode(9, &b) {
                Err(e) => {
                    assert!(matches!(e, MethodError::Corrupt { .. }), "{e}");
                    assert!(e.to_string().contains("node 9"), "{e}");
                }
                Ok(batch) => {
                    let h = NodeHeader::parse(9, &b).unwrap();
                    batch.validate().unwrap();
                    assert_eq!(batch.len(), h.count as usize);
                    for p in &batch.positions {
                        for (a, &x) in p.iter().enumerate() {
                            assert!(h.min[a] <= x && x <= h.max[a], "byte {i}");
                        }
                    }
                    for r in batch.radii.as_ref().unwrap() {
                        assert!(h.radius_min <= *r && *r <= h.radius_max, "byte {i}");
                    }
                    for &v in batch.normals.iter().flatten() {
                        assert!((octnormal::decode(v).length() - 1.0).abs() < 1e-5);
                    }
                }
            }
        }
    }
}
