//! Plots. STUB.
