//! Per-sample spacing estimate. STUB — to be implemented.

/// Distance to the k-th nearest neighbour of each point (see module docs).
pub fn knn_spacing(positions: &[[f32; 3]], k: usize) -> Vec<f32> {
    let _ = k;
    vec![1.0; positions.len()]
}
