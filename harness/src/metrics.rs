//! Image metrics. STUB.
