//! Building an SPT into a directory ([`build`], [`build_with_budget`]): the parameters
//! parsed, the list made in memory ([`list_in_memory`]) or in units ([`super::ooc`]), then
//! `index.json`, the manifest and the build's statistics.

use std::path::Path;
use std::time::Instant;

use rayon::prelude::*;
use scenes::{PointCloud, Progress};

use super::{
    FORMAT_VERSION, INDEX_FILE, InnerNodes, LOD_FILE, Listed, NAME, NODES_FILE, SptMode, SptParams,
    cluster_of, list, list_key, lod_entries, non_finite, ooc, quant,
};
use crate::{BuildStats, Manifest, MethodError, Params};

/// Builds the SPT of `cloud` into `dir`.
pub fn build(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let p = SptParams::parse(params, cloud.attributes())?;
    let budget = crate::spill::Budget {
        mem_bytes: p.mem_mb << 20,
        dir,
        hook: None,
    };
    build_with_budget(cloud, params, scene, progress, budget)
}

/// [`build`] within an explicit budget (tests force units with a tiny one, and damage the
/// spill files through its hook); the directory is `budget.dir`.
pub fn build_with_budget(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    progress: &dyn Progress,
    budget: crate::spill::Budget<'_>,
) -> Result<BuildStats, MethodError> {
    let p = SptParams::parse(params, cloud.attributes())?;
    let t0 = Instant::now();
    let n = cloud.len();
    let dir = budget.dir;
    let listed = if n as u64 <= ooc::unit_capacity(budget.mem_bytes) {
        list_in_memory(cloud, &p, dir, progress, t0)?
    } else {
        ooc::list_in_units(cloud, &p, budget, progress, t0)?
    };
    let index = &listed.index;
    crate::method::write_json(&dir.join(INDEX_FILE), index)?;
    let mut attrs = cloud.attributes();
    attrs.radii = true;
    Manifest {
        method: NAME.into(),
        format_version: FORMAT_VERSION,
        params: params.clone(),
        attributes: attrs,
        points: n as u64,
        scene: scene.into(),
    }
    .write(dir)?;
    let mut bytes_out = 0;
    for f in [NODES_FILE, LOD_FILE, INDEX_FILE] {
        let path = dir.join(f);
        bytes_out += std::fs::metadata(&path)
            .map_err(|e| MethodError::io(&path, e))?
            .len();
    }
    let mut extra = serde_json::Map::new();
    extra.insert("inner_nodes".into(), listed.inner.count.into());
    extra.insert("inner_eg_above_d".into(), listed.inner.eg_above_d.into());
    extra.insert(
        "inner_eg_over_d_max".into(),
        listed.inner.eg_over_d_max.into(),
    );
    extra.insert(
        "inner_eg_above_sphere".into(),
        listed.inner.eg_above_sphere.into(),
    );
    extra.insert(
        "inner_eg_over_sphere_max".into(),
        listed.inner.eg_over_sphere_max.into(),
    );
    extra.insert("clusters".into(), index.clusters.len().into());
    extra.insert("chunks".into(), index.chunks.len().into());
    extra.insert("tree_seconds".into(), listed.tree_seconds.into());
    extra.insert("leaf_radii_capped".into(), listed.radii_capped.into());
    extra.insert("units".into(), listed.units.into());
    Ok(BuildStats {
        points_in: n as u64,
        nodes: index.nodes,
        levels: index.levels,
        bytes_in: cloud.column_bytes(),
        bytes_out,
        seconds: t0.elapsed().as_secs_f64(),
        extra,
        ..Default::default()
    }
    .finish())
}

/// Builds the tree in memory and writes the list's files (not `index.json`).
fn list_in_memory(
    cloud: &PointCloud,
    p: &SptParams,
    dir: &Path,
    progress: &dyn Progress,
    t0: Instant,
) -> Result<Listed, MethodError> {
    let n = cloud.len();
    progress.start("spt: leaf radii", n as u64);
    let radii = crate::leaf::leaf_radii(cloud);
    progress.finish();
    progress.start("spt: point tree", n as u64);
    let tree = super::build::build_tree(cloud, &radii, p.color_threshold);
    progress.finish();
    let tree_seconds = t0.elapsed().as_secs_f64();
    let nodes = &tree.nodes;
    let has_normals = cloud.normals().is_some();
    let lod_scale = quant::LodScale::of(cloud.bounds());
    let lod = lod_entries(nodes);
    if let Some(i) = lod.iter().position(|l| !l.iter().all(|v| v.is_finite())) {
        return Err(non_finite(i as u64, &lod[i], &nodes[i]));
    }
    let cluster = |i: usize| cluster_of(p, has_normals, nodes[i].n);
    // The list order ([`list_key`]), sorted as packed 128-bit keys in parallel: each
    // comparison of a comparator recomputed two normal clusters, and the sort was a fifth of
    // the build (2 M points, `perf`).
    let mut keys: Vec<u128> = (0..nodes.len())
        .into_par_iter()
        .map(|i| list_key(cluster(i), &lod[i], i as u32))
        .collect();
    keys.par_sort_unstable();
    let mut w = list::ListWriter::create(
        dir,
        cloud.attributes(),
        &quant::Extent::of(nodes),
        lod_scale,
        keys.len() as u64,
        p.normal_clusters,
        p.mode == SptMode::Split,
    )?;
    progress.start("spt: writing", keys.len() as u64);
    // Each block's nodes gathered in list order in parallel (a random read per node), then
    // written in order.
    for block in keys.chunks(1 << 16) {
        let listed: Vec<list::ListNode> = block
            .par_iter()
            .map(|&k| {
                let i = k as u32 as usize;
                list::ListNode::of(&nodes[i], lod[i], cluster(i))
            })
            .collect();
        for nd in &listed {
            w.push(nd)?;
        }
        progress.inc(block.len() as u64);
    }
    let index = w.finish(tree.levels)?;
    progress.finish();
    Ok(Listed {
        index,
        inner: InnerNodes::of(nodes).0,
        radii_capped: radii.capped,
        tree_seconds,
        units: 1,
    })
}
