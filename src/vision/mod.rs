//! Stereo vision on images: the step before the formula, from a rectified pair to
//! correspondences and dense disparities (the `/depth-map` and `/match` engines will live here).
//!
//! The rule for everything in this module, as for [`crate::physics`]: pure functions on pixel
//! buffers and plain numbers. No HTTP, no serde, no async in any signature: the heavy route
//! group's handlers decode the request, call in here on a blocking thread, and encode the
//! answer. That keeps the engine testable on synthetic images, benchmarkable on its own, and
//! usable from the fuzz target without a server.
