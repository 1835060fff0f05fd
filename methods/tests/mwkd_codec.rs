//! MWKD node codec through the chunk store: nodes encoded, LZO-compressed and checksummed by
//! `RepoWriter`, read back by `Repository::read`; every flipped stored byte of a node is a
//! checksum error naming that node, the other nodes still decode.
#![allow(clippy::unwrap_used)]

use methods::MethodError;
use methods::mwkd::codec::{self, HEADER_BYTES};
use methods::store::{RepoWriter, Repository};
use scenes::rng::Pcg32;

fn node(n: usize, seed: u64, colors: bool) -> (Vec<u8>, codec::NodeHeader) {
    let mut rng = Pcg32::new(seed);
    // A spatially coherent strip, as tree nodes are.
    let points: Vec<[f32; 3]> = (0..n)
        .map(|i| {
            let t = i as f32 / n as f32;
            [
                t * 4.0,
                (t * 30.0).sin() * 0.2,
                1.0 + rng.range_f32(0.0, 0.01),
            ]
        })
        .collect();
    let radii: Vec<f32> = (0..n).map(|_| rng.range_f32(0.01, 0.02)).collect();
    let normals: Vec<[f32; 3]> = (0..n).map(|_| rng.unit_vec3().to_array()).collect();
    let cols: Vec<[u8; 3]> = (0..n).map(|i| [(i / 7) as u8, 128, 40]).collect();
    codec::encode(&points, &radii, Some(&normals), colors.then_some(&cols[..])).unwrap()
}

#[test]
fn store_round_trip_and_flipped_byte_names_the_node() -> Result<(), MethodError> {
    let dir = tempfile::tempdir().map_err(|e| MethodError::io("tempdir", e))?;
    let path = dir.path().join(codec::REPO_FILE);
    let nodes: Vec<(Vec<u8>, codec::NodeHeader)> =
        vec![node(500, 1, true), node(300, 2, false), node(1, 3, true)];
    for (bytes, h) in &nodes {
        let per_point = 6 + 1 + 2 + if h.colors { 3 } else { 0 };
        assert_eq!(bytes.len(), HEADER_BYTES + h.count as usize * per_point);
    }
    let mut w = RepoWriter::create(&path)?;
    let refs = nodes
        .iter()
        .map(|(b, _)| w.append(b))
        .collect::<Result<Vec<_>, _>>()?;
    w.finish()?;
    let repo = Repository::open(&path)?;
    for (id, ((bytes, _), r)) in nodes.iter().zip(&refs).enumerate() {
        let raw = repo.read(r, &format!("node {id}"))?;
        assert_eq!(&raw, bytes);
        let batch = codec::decode(id as u32, &raw)?;
        assert_eq!(batch, codec::decode(id as u32, bytes)?);
    }
    drop(repo);
    let clean = std::fs::read(&path).map_err(|e| MethodError::io(&path, e))?;
    let r = refs[1];
    for i in r.offset as usize..(r.offset + r.stored as u64) as usize {
        let mut bytes = clean.clone();
        bytes[i] ^= 0x5a;
        std::fs::write(&path, &bytes).map_err(|e| MethodError::io(&path, e))?;
        let repo = Repository::open(&path)?;
        let e = repo.read(&r, "node 1").unwrap_err();
        assert!(matches!(e, MethodError::Corrupt { .. }), "{e}");
        let s = e.to_string();
        assert!(
            s.contains("node 1") && s.contains("checksum"),
            "byte {i}: {s}"
        );
        assert_eq!(repo.read(&refs[0], "node 0")?, nodes[0].0);
        assert_eq!(repo.read(&refs[2], "node 2")?, nodes[2].0);
    }
    Ok(())
}
