//! tremorscan core: Chebyshev Phase Shifting structured light for measuring hand shape, colour and
//! tremor at 121 frames per second.
//!
//! Modules, from the bottom up (see `ARCHITECTURE.md`):
//! * [`pattern`]: one description for every phase-shifting codec, builders and pattern rendering.
//! * [`frame`]: 8-bit camera frames with time and pattern index.
//! * [`color`]: the cross-talk model `c = A·p + b`.
//! * [`calibrate`]: colour (cross-talk) calibration from the paper's Table 1 captures.
//! * [`geometry`]: lens models and rigid transforms.
//! * [`decode`]: window solve, robust unwrapping, combination, validity, sliding window.
//! * [`triangulate`]: decoded coordinates to an organised, coloured point cloud.
//! * [`rig`]: the virtual projector–camera rig with a trembling hand and exact ground truth.
//! * [`bench`]: the per-stage throughput check behind `tremorscan bench`.
//! * [`memory`]: this process's resident memory, for the bench and the progress lines.
//! * [`export`]: point clouds, depth maps, and trials' trajectories as Motion-BIDS and C3D.
//! * [`study`]: many sessions as one study: discovery, shards, freshness, the study table.

pub mod bench;
pub mod calibrate;
pub mod color;
pub mod decode;
pub mod device;
pub mod export;
pub mod frame;
pub mod geometry;
mod hash;
pub mod jsonfile;
pub mod memory;
pub mod pattern;
pub mod pipeline;
pub mod rig;
pub mod session;
pub mod study;
pub mod tremor;
pub mod triangulate;
