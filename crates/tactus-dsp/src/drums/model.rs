//! A trained drum transcription network ([`DrumModel`]): its input layout (steps 2 and 3
//! of the module docs) and its forward pass (step 4). The file formats it is read from are
//! in `format`.

use super::judge::SecondStage;
use super::retune::Retuning;
use super::CLASSES;
use crate::nn::{ConvNet, Layer};

/// A trained transcription network and its peak-picking thresholds.
#[derive(Clone, Debug, PartialEq)]
pub struct DrumModel {
    /// Mel bands per frame.
    pub bands: usize,
    /// Context frames before the current one.
    pub past: usize,
    /// Context frames after the current one.
    pub future: usize,
    /// Relative log floor (step 3).
    pub floor: f32,
    /// Whether the input also carries the positive first difference of the frames (step 3).
    pub flux: bool,
    /// `Some(ceil)`: the input also carries a second view, the backing beside the drum stem
    /// (step 3), normalised by the drum window's maximum and clipped to `[floor, ceil]`.
    pub backing: Option<f32>,
    /// Whether the input also carries the short view (file version 2, feature set 3): the
    /// same signal's mel frames from a frame half as long ([`MelConfig::drums_short`]), same
    /// context, normalised by their own window's maximum and clipped at `floor` (step 3).
    ///
    /// [`MelConfig::drums_short`]: crate::melbank::MelConfig::drums_short
    pub short: bool,
    /// Convolutional front layers (file version 4), run before the dense ones; `None` for a
    /// perceptron.
    pub conv: Option<ConvNet>,
    /// Dense layers; ReLU between them, sigmoid after the last.
    pub layers: Vec<Layer>,
    /// Activation threshold per class.
    pub thresholds: [f32; CLASSES],
    /// Further networks of an ensemble file, on the same input (same bands, context, floor
    /// and feature set): the activations are the mean of this network's and theirs. Their
    /// own thresholds are unused; empty for a single network.
    pub members: Vec<DrumModel>,
    /// Test-time retunings of a retuned file (`"TACTUSDT"`): the activations are the mean
    /// of the network's on each retuned window. Empty: one pass on the window as it is.
    pub retunings: Vec<Retuning>,
    /// The second stage of a staged file (`"TACTUSD2"`); `None`: every class is picked by
    /// its threshold alone.
    pub stage: Option<SecondStage>,
}

impl DrumModel {
    /// Scratch values [`DrumModel::forward`] needs in each of its three buffers.
    pub fn scratch_len(&self) -> usize {
        let own = self.own_scratch_len();
        self.members
            .iter()
            .map(Self::own_scratch_len)
            .fold(own, usize::max)
    }

    fn own_scratch_len(&self) -> usize {
        let mut widest = self.input_len().max(CLASSES);
        for l in &self.layers {
            widest = widest.max(l.n_in).max(l.n_out);
        }
        if let Some(net) = &self.conv {
            let (mut t, mut bands) = (self.past + 1 + self.future, self.bands);
            for c in &net.layers {
                widest = widest.max(c.c_out * (t + 1 - c.kt) * bands);
                let (_, to, bo) = c.out_shape(t, bands).expect("checked at load");
                (t, bands) = (to, bo);
            }
        }
        widest
    }

    /// Mel values in the context window: `bands · (past + 1 + future)`.
    pub fn window_len(&self) -> usize {
        self.bands * (self.past + 1 + self.future)
    }

    /// Values in one network input: the window, plus `bands · (past + future)` flux values
    /// if [`DrumModel::flux`], plus the second view's window if [`DrumModel::backing`] or
    /// [`DrumModel::short`].
    pub fn input_len(&self) -> usize {
        let flux = if self.flux {
            self.bands * (self.past + self.future)
        } else {
            0
        };
        let second = if self.has_second_view() {
            self.window_len()
        } else {
            0
        };
        self.window_len() + flux + second
    }

    /// Whether the input carries a second view of mel frames: the backing or the short view.
    pub fn has_second_view(&self) -> bool {
        self.backing.is_some() || self.short
    }

    /// Step 3 of the module docs: `window` holds `past + 1 + future` mel frames
    /// ([`DrumModel::window_len`] values), oldest first; writes the network input
    /// ([`DrumModel::input_len`] values).
    pub fn assemble(&self, window: &[f32], input: &mut [f32]) {
        self.assemble_window(window, input);
    }

    /// [`DrumModel::assemble`]; returns the window's maximum it subtracted.
    fn assemble_window(&self, window: &[f32], input: &mut [f32]) -> f32 {
        let m = window.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let n = window.len();
        let (x, d) = input.split_at_mut(n);
        for (o, &v) in x.iter_mut().zip(window) {
            *o = (v - m).max(self.floor);
        }
        if self.flux {
            let (prev, next) = (&x[..n - self.bands], &x[self.bands..]);
            for ((o, &p), &q) in d.iter_mut().zip(prev).zip(next) {
                *o = (q - p).max(0.0);
            }
        }
        m
    }

    /// [`DrumModel::assemble`] for a model with the backing view: `backing` holds the
    /// backing's mel frames of the same hops as `window`; its normalised values (the drum
    /// window's maximum subtracted, clipped to `[floor, ceil]`) follow the drum view's. For
    /// any other model `backing` is ignored.
    ///
    /// For a model with the short view, `backing` holds the short view's frames instead;
    /// they are normalised by their own window's maximum and clipped at `floor`.
    pub fn assemble_with_backing(&self, window: &[f32], backing: &[f32], input: &mut [f32]) {
        let m = self.assemble_window(window, input);
        let n = window.len();
        if self.short {
            let ms = backing.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            for (o, &v) in input[n..2 * n].iter_mut().zip(backing) {
                *o = (v - ms).max(self.floor);
            }
            return;
        }
        let Some(ceil) = self.backing else {
            return;
        };
        for (o, &v) in input[n..2 * n].iter_mut().zip(backing) {
            *o = (v - m).clamp(self.floor, ceil);
        }
    }

    /// Runs the network on one assembled input; `a`, `b` and `c` are scratch buffers of
    /// [`DrumModel::scratch_len`] values. Returns the activations: for an ensemble, the mean
    /// of its members' (this network's first, then [`DrumModel::members`] in order).
    pub fn forward(
        &self,
        input: &[f32],
        a: &mut [f32],
        b: &mut [f32],
        c: &mut [f32],
    ) -> [f32; CLASSES] {
        if !self.retunings.is_empty() {
            // A perceptron on mel frames and perhaps the short view (checked at load): `c`
            // is free for the retuned input, each view retuned and normalised on its own.
            let (w, rest) = c.split_at_mut(input.len());
            let view = self.window_len();
            let mut out = [0f32; CLASSES];
            for r in &self.retunings {
                let o = if r.is_identity() {
                    self.forward_one(input, a, b, rest)
                } else {
                    for (src, dst) in input.chunks_exact(view).zip(w.chunks_exact_mut(view)) {
                        r.apply(src, self.floor, dst);
                    }
                    self.forward_one(w, a, b, rest)
                };
                for (x, y) in out.iter_mut().zip(o) {
                    *x += y;
                }
            }
            let n = self.retunings.len() as f32;
            return out.map(|x| x / n);
        }
        let mut out = self.forward_one(input, a, b, c);
        if self.members.is_empty() {
            return out;
        }
        for m in &self.members {
            let o = m.forward_one(input, a, b, c);
            for (x, y) in out.iter_mut().zip(o) {
                *x += y;
            }
        }
        let n = (1 + self.members.len()) as f32;
        out.map(|x| x / n)
    }

    /// [`DrumModel::forward`] on `count` assembled inputs at once (`inputs`: `count` rows of
    /// [`DrumModel::input_len`] values), the activations into `out[..count]`. Each hop's
    /// activations are `forward`'s on its input alone, bit for bit: every pass runs
    /// [`crate::nn::mlp::run_layers_batch`], whose outputs do not depend on the batch, and
    /// the passes are averaged in the same order. What batching buys: one read of a weight
    /// row serves every hop of the batch ([`crate::nn`]'s AVX2 kernel meets four hops and two
    /// rows at once). A convolutional model runs its hops one at a time.
    pub fn forward_batch(
        &self,
        inputs: &[f32],
        count: usize,
        s: &mut BatchScratch,
        out: &mut [[f32; CLASSES]],
    ) {
        let len = self.input_len();
        s.fit(self, count);
        let convolutional = self.conv.is_some() || self.members.iter().any(|m| m.conv.is_some());
        if convolutional {
            for (x, o) in inputs.chunks_exact(len).zip(out.iter_mut()).take(count) {
                *o = self.forward(x, &mut s.a, &mut s.b, &mut s.c);
            }
            return;
        }
        let out = &mut out[..count];
        if !self.retunings.is_empty() {
            let view = self.window_len();
            out.fill([0.0; CLASSES]);
            for r in &self.retunings {
                let x = if r.is_identity() {
                    &inputs[..count * len]
                } else {
                    for (src, dst) in inputs[..count * len]
                        .chunks_exact(len)
                        .zip(s.c.chunks_exact_mut(len))
                    {
                        for (v, w) in src.chunks_exact(view).zip(dst.chunks_exact_mut(view)) {
                            r.apply(v, self.floor, w);
                        }
                    }
                    &s.c[..count * len]
                };
                self.forward_own_batch(x, count, &mut s.a, &mut s.b, &mut |h, o| {
                    for (x, y) in out[h].iter_mut().zip(o) {
                        *x += y;
                    }
                });
            }
            let n = self.retunings.len() as f32;
            for o in out.iter_mut() {
                *o = o.map(|x| x / n);
            }
            return;
        }
        self.forward_own_batch(inputs, count, &mut s.a, &mut s.b, &mut |h, o| out[h] = o);
        if self.members.is_empty() {
            return;
        }
        for m in &self.members {
            m.forward_own_batch(inputs, count, &mut s.a, &mut s.b, &mut |h, o| {
                for (x, y) in out[h].iter_mut().zip(o) {
                    *x += y;
                }
            });
        }
        let n = (1 + self.members.len()) as f32;
        for o in out.iter_mut() {
            *o = o.map(|x| x / n);
        }
    }

    /// This perceptron's activations alone (members ignored) on `count` inputs, handed to
    /// `each(hop, activations)` in order.
    fn forward_own_batch(
        &self,
        inputs: &[f32],
        count: usize,
        a: &mut [f32],
        b: &mut [f32],
        each: &mut dyn FnMut(usize, [f32; CLASSES]),
    ) {
        let z = crate::nn::mlp::run_layers_batch(&self.layers, inputs, count, a, b);
        let n = z.len() / count.max(1);
        for (h, row) in z.chunks_exact(n).enumerate() {
            let mut o = [0f32; CLASSES];
            for (o, &z) in o.iter_mut().zip(row) {
                *o = 1.0 / (1.0 + (-z).exp());
            }
            each(h, o);
        }
    }

    /// This network's activations alone (members ignored).
    fn forward_one(
        &self,
        input: &[f32],
        a: &mut [f32],
        b: &mut [f32],
        c: &mut [f32],
    ) -> [f32; CLASSES] {
        let src = match &self.conv {
            None => crate::nn::mlp::run_layers(&self.layers, input, a, b),
            Some(net) => {
                let n = input.len();
                for (((o, &x), &m), &s) in c[..n].iter_mut().zip(input).zip(&net.mean).zip(&net.std)
                {
                    *o = (x - m) / s;
                }
                let (mut t, mut bands) = (self.past + 1 + self.future, self.bands);
                let (mut src, mut dst) = (&mut *c, &mut *b);
                for l in &net.layers {
                    l.run(src, t, bands, a, dst);
                    let (_, to, bo) = l.out_shape(t, bands).expect("checked at load");
                    (t, bands) = (to, bo);
                    std::mem::swap(&mut src, &mut dst);
                }
                let flat = self.layers[0].n_in;
                // `a` is free again: the dense layers take their input from it.
                let (x, _) = src.split_at(flat);
                crate::nn::mlp::run_layers(&self.layers, x, a, dst)
            }
        };
        let mut out = [0f32; CLASSES];
        for (o, &z) in out.iter_mut().zip(src.iter()) {
            *o = 1.0 / (1.0 + (-z).exp());
        }
        out
    }
}

/// Scratch of [`DrumModel::forward_batch`]: grown to the largest batch it has met, then
/// reused (no allocation after the first batch of that size).
#[derive(Debug, Default)]
pub struct BatchScratch {
    a: Vec<f32>,
    b: Vec<f32>,
    c: Vec<f32>,
}

impl BatchScratch {
    /// Scratch for batches of up to `count` hops of `model`.
    pub fn new(model: &DrumModel, count: usize) -> BatchScratch {
        let mut s = BatchScratch::default();
        s.fit(model, count);
        s
    }

    fn fit(&mut self, model: &DrumModel, count: usize) {
        let n = model.scratch_len() * count.max(1);
        for v in [&mut self.a, &mut self.b, &mut self.c] {
            if v.len() < n {
                v.resize(n, 0.0);
            }
        }
    }
}
