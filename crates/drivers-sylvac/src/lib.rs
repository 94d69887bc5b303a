//! Sylvac gauge driver (work in progress).
