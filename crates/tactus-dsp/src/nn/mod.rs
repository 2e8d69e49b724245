//! The small networks embedded in the crate, as generic pieces: the drum transcriber
//! ([`crate::drums`]) and the learned pitch salience ([`crate::bassnet`]) are built from
//! them, and they know neither.
//!
//! | module | what |
//! |---|---|
//! | [`layer`] | [`Layer`]: one dense layer, `out = W · in + b` |
//! | [`conv`] | [`Conv`], [`ConvNet`]: convolution over (time × band) maps, ReLU, max-pool |
//! | `mlp` | the forward pass of a chain of dense layers, one input or a batch at a time |
//! | `format` | the weight-file pieces both model files share: little-endian values, layer chains |
//! | `simd` | the dense layer compiled for AVX2, chosen at run time |
//!
//! Every output is computed in one fixed order of arithmetic (eight lanes, then the bias,
//! then the tail), so a network gives the same bits on every run, for any batching and on
//! every CPU (the AVX2 path included).

pub mod conv;
pub(crate) mod format;
pub mod layer;
pub(crate) mod mlp;
mod simd;

pub use conv::{Conv, ConvNet};
pub use layer::Layer;
