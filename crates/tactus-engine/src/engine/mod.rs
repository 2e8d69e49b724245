//! The streaming engine: separator → per-stem chains → bins → glove frames.
//!
//! One [`Engine`] serves both drivers. It accepts planar stereo blocks of any size at the
//! engine rate, plus optional stems supplied directly (`render --stem`), and builds only
//! what the glove map needs: a drums-only map runs no pitch tracking and asks the
//! separator for drums alone. Offline, each chain keeps a thread of its own for the whole
//! song and the calling thread separates ahead of them ([`workers`]); otherwise chains run
//! on scoped threads when a block is large enough to pay for it. Results do not depend on
//! the block size or on threading, because every stage is chunk-invariant.

mod chain;
mod config;
mod frames;
mod report;
mod separator;
mod workers;

pub use config::{EngineConfig, SeparatorChoice, StageTimes, ENGINE_RATE};

use std::time::{Duration, Instant};

use tactus_dsp::dc::DcBlock;
use tactus_dsp::{Band, SampleStage, Stem};
use tactus_separate::{SegmentStats, Separator, StemOutput, StemSet};

use crate::profile::Profile;
use crate::recipe::{recipe, Role, Source};
use crate::track::{Geometry, Mode};
use crate::EngineError;
use chain::{feed, StemChain};
use workers::{Block, Workers};

/// Blocks at least this long are processed with one thread per stem chain.
const PARALLEL_MIN_BLOCK: usize = 16_384;

/// A separated block and copies of the supplied stems' same span, waiting for the chains.
type PendingBlock = (StemOutput, Vec<(Stem, Vec<f32>)>);

/// The streaming pipeline. See the module docs.
pub struct Engine {
    cfg: EngineConfig,
    geo: Geometry,
    separator: Option<Box<dyn Separator>>,
    sep_out: StemOutput,
    chains: Vec<StemChain>,
    n_in: usize,
    t_separate: Duration,
    /// A separated block (with copies of the supplied stems) waiting for the chains.
    pending: Option<PendingBlock>,
    /// The live profile's drums listen to the mono mix: its samples of the current block.
    mix: Vec<f32>,
    /// Whether the drum chain takes the mix rather than a separated stem.
    drums_on_mix: bool,
    /// Bins forgotten by [`Engine::discard_before`]: the tracks' bin vectors start here.
    bin_base: usize,
    /// DC removal of the mix's channels ([`tactus_dsp::dc`]) and their current block.
    dc: [DcBlock; 2],
    dc_out: [Vec<f32>; 2],
    /// Offline, pipelined and parallel: the chains on threads of their own from the first
    /// block to [`Engine::finish`] (`workers`); `chains` is empty meanwhile.
    workers: Option<Workers>,
    /// The chains' stems, in order (also while the workers hold the chains).
    stem_list: Vec<Stem>,
}

impl Engine {
    /// Builds the stages the map needs.
    pub fn new(cfg: EngineConfig) -> Result<Engine, EngineError> {
        if cfg.bin_ms == 0 {
            return Err(EngineError::Config(
                "bin length must be at least 1 ms".into(),
            ));
        }
        if cfg.levels == 0 {
            return Err(EngineError::Config("levels must be at least 1".into()));
        }
        let bin_samples = (cfg.sample_rate as u64 * cfg.bin_ms as u64 / 1000).max(1) as usize;
        let geo = Geometry {
            sample_rate: cfg.sample_rate,
            bin_samples,
            levels: cfg.levels,
            mode: cfg.mode,
            level_rule: cfg.level_rule,
            profile: cfg.profile,
        };
        let needs = cfg.map.needs();
        let mut chains = Vec::new();
        let mut separated = StemSet::default();
        for stem in cfg.map.stems() {
            let source = Source::of(cfg.supplied.contains(stem), cfg.separator.kind());
            let stem_recipe = Role::of(stem)
                .map(|role| recipe(role, source, cfg.profile, cfg.separator.kind(), cfg.pitch));
            let notes = needs.note_onsets.contains(&stem).then_some(cfg.note_rule);
            let bands: Vec<Band> = if stem == Stem::Drums {
                needs.bands.clone()
            } else {
                Vec::new()
            };
            let chain = StemChain::new(
                stem,
                geo,
                stem_recipe.as_ref(),
                needs.pitch.contains(&stem),
                notes,
                &bands,
                &cfg.drums,
            )?;
            let wants_backing = chain.wants_backing();
            chains.push(chain);
            // The live profile's drum chain listens to the mix: no separator latency.
            let on_mix = stem == Stem::Drums && cfg.profile == Profile::Live;
            if !cfg.supplied.contains(stem) && !on_mix {
                separated = separated.with(stem);
                // The drum transcriber's backing view and the lead's harmonic view: the
                // spectral separator's other stems (trained on those; other separators'
                // stems go without them, as clean stems do).
                if wants_backing && cfg.separator == SeparatorChoice::Spectral {
                    separated = separated
                        .with(Stem::Bass)
                        .with(Stem::Vocals)
                        .with(Stem::Other);
                }
            }
        }
        let separator = separator::separator_for(&cfg, separated)?;
        let stem_list = chains.iter().map(|c| c.stem).collect();
        let drums_on_mix = cfg.profile == Profile::Live
            && !cfg.supplied.contains(Stem::Drums)
            && chains.iter().any(|c| c.stem == Stem::Drums);
        Ok(Engine {
            mix: Vec::with_capacity(if drums_on_mix {
                PARALLEL_MIN_BLOCK * 4
            } else {
                0
            }),
            drums_on_mix,
            sep_out: StemOutput::with_capacity(separated, PARALLEL_MIN_BLOCK * 4),
            dc: [
                DcBlock::new(geo.sample_rate)?,
                DcBlock::new(geo.sample_rate)?,
            ],
            cfg,
            geo,
            separator,
            chains,
            n_in: 0,
            t_separate: Duration::ZERO,
            pending: None,
            bin_base: 0,
            dc_out: [Vec::new(), Vec::new()],
            workers: None,
            stem_list,
        })
    }

    /// The configuration the engine was built with.
    pub fn config(&self) -> &EngineConfig {
        &self.cfg
    }

    /// Stems the engine computes features for.
    pub fn stems(&self) -> Vec<Stem> {
        self.stem_list.clone()
    }

    /// Name of the separator that runs, if any.
    pub fn separator_name(&self) -> Option<&'static str> {
        self.separator.as_ref().map(|s| s.name())
    }

    /// The separator's per-segment timing, if it runs a network in segments (the ONNX
    /// separators; see [`Separator::segment_stats`]).
    pub fn segment_stats(&self) -> Option<SegmentStats> {
        self.separator.as_ref().and_then(|s| s.segment_stats())
    }

    /// The separator's run-time failure since the last call, if any
    /// ([`Separator::take_error`]), or the ADTLib drum network's: drivers check after
    /// every block and after [`Engine::finish`], and stop with [`EngineError::Separator`]
    /// or [`EngineError::Drums`].
    pub fn take_separator_error(&mut self) -> Option<EngineError> {
        if let Some(e) = self.separator.as_mut().and_then(|s| s.take_error()) {
            return Some(EngineError::Separator(e));
        }
        self.chains
            .iter_mut()
            .find_map(|c| c.classes.as_mut().and_then(|t| t.take_error()))
            .map(EngineError::Drums)
    }

    /// Feeds one block of the mix (planar stereo; pass the same slice twice for mono) and
    /// the same span of every supplied stem. All slices must have the same length.
    pub fn process(&mut self, left: &[f32], right: &[f32], supplied: &[(Stem, &[f32])]) {
        let [mut l, mut r] = std::mem::take(&mut self.dc_out);
        for ((buf, x), dc) in [&mut l, &mut r]
            .into_iter()
            .zip([left, right])
            .zip(&mut self.dc)
        {
            buf.clear();
            buf.extend_from_slice(x);
            dc.process_inplace(buf);
        }
        self.process_mix(&l, &r, supplied);
        self.dc_out = [l, r];
    }

    fn process_mix(&mut self, left: &[f32], right: &[f32], supplied: &[(Stem, &[f32])]) {
        if self.drums_on_mix {
            // The live profile: the drum chain takes the mono mix, as if it were supplied.
            let mut mix = std::mem::take(&mut self.mix);
            mix.clear();
            mix.extend(left.iter().zip(right).map(|(l, r)| 0.5 * (l + r)));
            let mut with_mix: Vec<(Stem, &[f32])> = Vec::with_capacity(supplied.len() + 1);
            with_mix.extend_from_slice(supplied);
            with_mix.push((Stem::Drums, &mix));
            self.process_inner(left, right, &with_mix);
            self.mix = mix;
        } else {
            self.process_inner(left, right, supplied);
        }
    }

    fn process_inner(&mut self, left: &[f32], right: &[f32], supplied: &[(Stem, &[f32])]) {
        self.n_in += left.len();
        if self.cfg.pipeline && self.cfg.parallel && self.separator.is_some() {
            if self.cfg.mode == Mode::Offline && (self.workers.is_some() || self.chains.len() > 1) {
                self.process_on_workers(left, right, supplied);
            } else {
                self.process_pipelined(left, right, supplied);
            }
            return;
        }
        if let Some(sep) = &mut self.separator {
            let t = Instant::now();
            self.sep_out.clear();
            sep.process(left, right, &mut self.sep_out);
            self.t_separate += t.elapsed();
        }
        feed(&mut self.chains, &self.sep_out, supplied, self.cfg.parallel);
    }

    /// Separates this block on the calling thread and queues it for the chains' own threads
    /// ([`workers`]), started on the first block.
    fn process_on_workers(&mut self, left: &[f32], right: &[f32], supplied: &[(Stem, &[f32])]) {
        let Some(sep) = self.separator.as_mut() else {
            return;
        };
        let workers = self
            .workers
            .get_or_insert_with(|| Workers::start(std::mem::take(&mut self.chains)));
        let mut out = self.sep_out.clone();
        out.clear();
        let t = Instant::now();
        sep.process(left, right, &mut out);
        self.t_separate += t.elapsed();
        let supplied = supplied.iter().map(|(st, x)| (*st, x.to_vec())).collect();
        workers.send(Block { out, supplied });
    }

    /// Separates this block on the calling thread while the chains work on the previous one.
    fn process_pipelined(&mut self, left: &[f32], right: &[f32], supplied: &[(Stem, &[f32])]) {
        let Engine {
            separator,
            sep_out,
            chains,
            pending,
            t_separate,
            ..
        } = self;
        let Some(sep) = separator.as_mut() else {
            return;
        };
        let prev = pending.take();
        // Reuse the buffer of the block before last for this block's output.
        let mut out = std::mem::take(sep_out);
        out.clear();
        std::thread::scope(|s| {
            if let Some((p_out, p_sup)) = &prev {
                let chains = &mut *chains;
                s.spawn(move || {
                    let views: Vec<(Stem, &[f32])> =
                        p_sup.iter().map(|(st, v)| (*st, v.as_slice())).collect();
                    feed(chains, p_out, &views, true);
                });
            }
            let t = Instant::now();
            sep.process(left, right, &mut out);
            *t_separate += t.elapsed();
        });
        let copies = supplied.iter().map(|(st, x)| (*st, x.to_vec())).collect();
        *pending = Some((out, copies));
        if let Some((p_out, _)) = prev {
            *sep_out = p_out;
        }
    }

    /// Ends the stream: flushes the separator and every chain, and (offline) computes the
    /// whole-track statistics.
    pub fn finish(&mut self) {
        if let Some(workers) = self.workers.take() {
            if let Some(sep) = &mut self.separator {
                let mut out = self.sep_out.clone();
                out.clear();
                let t = Instant::now();
                sep.finish(&mut out);
                self.t_separate += t.elapsed();
                workers.send(Block {
                    out,
                    supplied: Vec::new(),
                });
            }
            self.chains = workers.join();
            self.finish_chains();
            return;
        }
        if let Some((p_out, p_sup)) = self.pending.take() {
            let views: Vec<(Stem, &[f32])> =
                p_sup.iter().map(|(st, v)| (*st, v.as_slice())).collect();
            feed(&mut self.chains, &p_out, &views, self.cfg.parallel);
        }
        if let Some(sep) = &mut self.separator {
            let t = Instant::now();
            self.sep_out.clear();
            sep.finish(&mut self.sep_out);
            self.t_separate += t.elapsed();
            feed(&mut self.chains, &self.sep_out, &[], self.cfg.parallel);
        }
        self.finish_chains();
    }

    /// Ends every chain's stream (offline: on one thread each).
    fn finish_chains(&mut self) {
        let parallel = self.cfg.parallel && self.chains.len() > 1 && self.cfg.mode == Mode::Offline;
        if parallel {
            std::thread::scope(|s| {
                for c in &mut self.chains {
                    s.spawn(move || c.finish());
                }
            });
        } else {
            for c in &mut self.chains {
                c.finish();
            }
        }
    }

    /// Samples fed so far.
    pub fn samples_in(&self) -> usize {
        self.n_in
    }

    /// Bin length in samples.
    pub fn bin_samples(&self) -> usize {
        self.geo.bin_samples
    }

    /// Number of bins the whole stream has (after [`Engine::finish`]).
    pub fn total_bins(&self) -> usize {
        self.n_in.div_ceil(self.geo.bin_samples)
    }

    /// Back to the just-constructed state.
    pub fn reset(&mut self) {
        if let Some(s) = &mut self.separator {
            s.reset();
        }
        self.sep_out.clear();
        if let Some(w) = self.workers.take() {
            self.chains = w.join();
        }
        for c in &mut self.chains {
            c.reset();
        }
        self.n_in = 0;
        self.t_separate = Duration::ZERO;
        self.pending = None;
        self.bin_base = 0;
        for d in &mut self.dc {
            d.reset();
        }
    }
}
