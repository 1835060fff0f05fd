//! Camera paths. STUB — to be implemented.
