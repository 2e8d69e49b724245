//! One dense layer of the embedded networks: its shape and weights.

/// One dense layer, `out = W · in + b`, `W` row-major `[n_out][n_in]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    /// Inputs.
    pub n_in: usize,
    /// Outputs.
    pub n_out: usize,
    /// Weights, `n_out × n_in`, row-major.
    pub w: Vec<f32>,
    /// Biases, `n_out`.
    pub b: Vec<f32>,
}
