//! Image metrics
