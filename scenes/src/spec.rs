//! Scene specifications. STUB — to be implemented.

/// A parsed scene spec.
#[derive(Debug, Clone)]
pub struct SceneSpec;
