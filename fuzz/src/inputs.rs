//! Inputs: a seed file with 1–4 stacked mutations, drawn from `Pcg32::stream(seed, i)`.

use methods::store::ChunkRef;
use scenes::rng::Pcg32;

use crate::mutate;

use crate::corpus::{Corpus, Input};
use crate::targets::Target;

// ---------------------------------------------------------------------------------------------
// Inputs
// ---------------------------------------------------------------------------------------------

/// Recomputes the checksums a format keeps over bytes a mutation may have changed, so the
/// input reaches the decoder behind the check (a mismatch would stop nearly every input).
fn reseal(name: &str, b: &mut [u8]) {
    let fnv = scenes::hash::fnv1a64;
    if name.ends_with(".sbc") && b.len() >= 128 {
        let sum = fnv(&b[..120]);
        mutate::put_le(b, 120, 8, sum);
    } else if name == "tree.qs" && b.len() >= 80 {
        let sum = scenes::hash::Fnv64::default()
            .write(&b[..72])
            .write(&b[80..])
            .finish();
        mutate::put_le(b, 72, 8, sum);
    } else if (name == "lod.bin" || name == "nodes.bin") && b.len() >= 24 {
        let sum = fnv(&b[24..]);
        mutate::put_le(b, 16, 8, sum);
    } else if name.ends_with(".e57") {
        mutate::reseal_e57(b);
    } else if name == "index.bin" && b.len() >= 24 {
        let sum = methods::store::checksum(&b[24..]);
        mutate::put_le(b, 16, 8, sum);
    }
}

/// Chunk references with checksums recomputed over `repo`'s bytes where they lie inside.
pub(crate) fn resealed_refs(refs: &[ChunkRef], repo: &[u8]) -> Vec<ChunkRef> {
    refs.iter()
        .map(|r| {
            let mut r = *r;
            let start = r.offset as usize;
            if let Some(s) = start
                .checked_add(r.stored as usize)
                .and_then(|end| repo.get(start..end))
            {
                r.checksum = methods::store::checksum(s);
            }
            r
        })
        .collect()
}

/// Input `i` of the stream `seed`: a seed file and 1–4 stacked mutations, drawn from
/// `Pcg32::stream(seed, i)` alone, so any input can be made again from `(seed, i)`.
pub fn input(target: Target, corpus: &Corpus, seed: u64, i: u64) -> Input {
    if target == Target::SelfTest {
        return Input {
            seed: 0,
            bytes: i.to_le_bytes().to_vec(),
        };
    }
    let mut r = Pcg32::stream(seed, i);
    let n = corpus.seeds.len();
    let pick = mutate::below(&mut r, n);
    let other = mutate::below(&mut r, n);
    let s = &corpus.seeds[pick];
    let mut b = s.bytes.clone();
    let aware = |r: &mut Pcg32, b: &mut Vec<u8>| match target {
        Target::PlyAscii | Target::PlyBinary => mutate::ply(r, b),
        Target::Pcd => mutate::pcd(r, b),
        Target::Las | Target::Laz => mutate::las(r, b),
        Target::SceneToml | Target::PathToml => mutate::toml(r, b),
        Target::Method(_) if s.name.ends_with(".json") => mutate::toml(r, b),
        _ => {}
    };
    for _ in 0..1 + r.below(4) {
        if r.below(2) == 0 {
            aware(&mut r, &mut b);
        } else {
            mutate::bytes(&mut r, &mut b, &corpus.seeds[other].bytes);
        }
    }
    if r.below(8) != 0 {
        reseal(&s.name, &mut b);
    }
    Input {
        seed: pick,
        bytes: b,
    }
}
