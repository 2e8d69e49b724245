//! One stem's chain: its denoiser, then its tracks (pitch, note onsets, drum classes or
//! bands), fed block by block, on threads of their own when a block is large.

use std::time::{Duration, Instant};

use tactus_dsp::sos::SosFilter;
use tactus_dsp::{Band, SampleStage, Stem};
use tactus_glove::BinFeatures;
use tactus_separate::StemOutput;

use super::PARALLEL_MIN_BLOCK;
use crate::drums::{ClassTrack, DrumMethod};
use crate::notes::{NoteRule, NoteTrack, PitchNotes};
use crate::recipe::Recipe;
use crate::track::{held, Denoise, Feature, Geometry, OnsetTrack, PitchTrack, Track, TrackInput};
use crate::EngineError;

/// One drum band: band-pass filter then onset track.
pub(super) struct BandTrack {
    pub(super) band: Band,
    pub(super) filter: SosFilter,
    pub(super) track: OnsetTrack,
    pub(super) scratch: Vec<f32>,
    pub(super) t_filter: Duration,
    pub(super) t_onsets: Duration,
}

impl Track for BandTrack {
    fn process(&mut self, input: &TrackInput<'_>) {
        let t = Instant::now();
        self.scratch.clear();
        self.scratch.extend_from_slice(input.stem);
        self.filter.process_inplace(&mut self.scratch);
        let t2 = Instant::now();
        self.track.process(&self.scratch);
        self.t_filter += t2 - t;
        self.t_onsets += t2.elapsed();
    }

    fn finish(&mut self, _: &TrackInput<'_>) {
        let t = Instant::now();
        self.track.finish();
        self.t_onsets += t.elapsed();
    }

    fn reset(&mut self) {
        self.filter.reset();
        self.track.reset();
    }

    fn latency_samples(&self) -> usize {
        self.track.latency_samples()
    }

    fn discard_before(&mut self, bins: usize) {
        self.track.discard(bins);
    }

    fn feature(&self) -> Feature {
        Feature::Beats
    }

    fn ready_bins(&self) -> usize {
        self.track.beats.bins.len()
    }

    fn read_bin(&self, bin: usize, hold: usize, _stem: Stem, frame: &mut BinFeatures) {
        frame.band_beat[self.band as usize] = held(&self.track.beats.bins, bin, hold);
    }

    fn retained(&self) -> usize {
        self.track.retained()
    }
}

/// Everything computed from one stem: its denoiser, then its tracks ([`Track`]).
pub(super) struct StemChain {
    pub(super) stem: Stem,
    pub(super) denoise: Denoise,
    pub(super) buf: Vec<f32>,
    pub(super) pitch: Option<PitchTrack>,
    pub(super) notes: Option<NoteTrack>,
    pub(super) bands: Vec<BandTrack>,
    /// The per-instrument transcriber (drums with [`DrumMethod::Classes`]).
    pub(super) classes: Option<ClassTrack>,
    /// The spectral separator's harmonic sum (bass + vocals + other) beside the stem, and
    /// its denoiser (the stem's): the backing of a drum transcriber that reads it
    /// ([`ClassTrack::wants_backing`]), or the harmonic view of the lead's learned pair
    /// ([`crate::recipe::Recipe::harmonic_view`]).
    pub(super) backing: Option<(Denoise, Vec<f32>)>,
    pub(super) samples: usize,
    pub(super) t_denoise: Duration,
    pub(super) t_pitch: Duration,
    pub(super) t_notes: Duration,
    pub(super) t_classes: Duration,
}

/// The per-instrument drum transcriber `drums` asks for, when a map shows any of `bands`.
fn class_track(
    geo: Geometry,
    bands: &[Band],
    drums: &DrumMethod,
) -> Result<Option<ClassTrack>, EngineError> {
    let mut track = match drums {
        _ if bands.is_empty() => return Ok(None),
        DrumMethod::Classes => ClassTrack::new(geo)?,
        DrumMethod::ClassesLive => ClassTrack::live(geo)?,
        DrumMethod::ClassesFile(path) => ClassTrack::from_file(geo, path)?,
        #[cfg(feature = "onnx")]
        DrumMethod::AdtLib(model) => ClassTrack::adtlib(geo, model, 0)?,
        #[cfg(not(feature = "onnx"))]
        DrumMethod::AdtLib(_) => {
            return Err(EngineError::Config(
                "--drums adtlib needs a tactus built with `--features onnx` (see docs/install.md, \"ONNX models\")".into(),
            ))
        }
        DrumMethod::Bands => return Ok(None),
    };
    track.show(bands);
    Ok(Some(track))
}

/// The band tracks of `bands` (a band above Nyquist, e.g. cymbals at 8 kHz, is skipped; it
/// stays silent).
fn band_tracks(geo: Geometry, bands: &[Band]) -> Result<Vec<BandTrack>, EngineError> {
    let mut out = Vec::new();
    for &band in bands {
        let edges = tactus_dsp::sos::band_edges(band, geo.sample_rate);
        if let (Ok(filter), Some((lo, hi))) = (SosFilter::band(band, geo.sample_rate), edges) {
            out.push(BandTrack {
                band,
                filter,
                track: OnsetTrack::new(geo, Some((lo as f32, hi as f32)))?,
                scratch: Vec::with_capacity(PARALLEL_MIN_BLOCK * 4),
                t_filter: Duration::ZERO,
                t_onsets: Duration::ZERO,
            });
        }
    }
    Ok(out)
}

impl StemChain {
    /// The chain of `stem`: its pitch track and note onsets as `recipe` says (a melodic
    /// stem; the pitch track when `pitch`, note onsets by `notes`), its drum `bands` or
    /// classes by `drums`.
    pub(super) fn new(
        stem: Stem,
        geo: Geometry,
        recipe: Option<&Recipe>,
        pitch: bool,
        notes: Option<NoteRule>,
        bands: &[Band],
        drums: &DrumMethod,
    ) -> Result<Self, EngineError> {
        let hp = if matches!(stem, Stem::Bass | Stem::Drums) {
            30.0
        } else {
            60.0
        };
        let pitch = match recipe {
            Some(r) if pitch => Some(PitchTrack::new(geo, r)?),
            _ => None,
        };
        let notes = match (notes, &pitch, recipe) {
            (Some(rule), Some(p), Some(r)) => {
                Some(NoteTrack::Pitch(PitchNotes::new(geo, p, rule, r.notes)?))
            }
            (Some(_), _, _) => Some(NoteTrack::Flux(OnsetTrack::new(geo, None)?)),
            (None, _, _) => None,
        };
        let harmonic_view = recipe.is_some_and(|r| r.harmonic_view);
        let classes = class_track(geo, bands, drums)?;
        let bands = if classes.is_some() { &[][..] } else { bands };
        let reads_backing = classes.as_ref().is_some_and(|c| c.wants_backing());
        let backing = if reads_backing || (harmonic_view && pitch.is_some()) {
            Some((Denoise::new(hp, geo.sample_rate)?, Vec::new()))
        } else {
            None
        };
        Ok(StemChain {
            stem,
            denoise: Denoise::new(hp, geo.sample_rate)?,
            buf: Vec::with_capacity(PARALLEL_MIN_BLOCK * 4),
            pitch,
            notes,
            bands: band_tracks(geo, bands)?,
            classes,
            backing,
            samples: 0,
            t_denoise: Duration::ZERO,
            t_pitch: Duration::ZERO,
            t_notes: Duration::ZERO,
            t_classes: Duration::ZERO,
        })
    }

    /// The chain's tracks, in the order they run: pitch, note onsets, drum classes, bands.
    pub(super) fn tracks(&self) -> impl Iterator<Item = &dyn Track> {
        let pitch = self.pitch.iter().map(|t| t as &dyn Track);
        let notes = self.notes.iter().map(|t| t as &dyn Track);
        let classes = self.classes.iter().map(|t| t as &dyn Track);
        let bands = self.bands.iter().map(|t| t as &dyn Track);
        pitch.chain(notes).chain(classes).chain(bands)
    }

    /// [`StemChain::tracks`], to change.
    pub(super) fn tracks_mut(&mut self) -> impl Iterator<Item = &mut dyn Track> {
        let pitch = self.pitch.iter_mut().map(|t| t as &mut dyn Track);
        let notes = self.notes.iter_mut().map(|t| t as &mut dyn Track);
        let classes = self.classes.iter_mut().map(|t| t as &mut dyn Track);
        let bands = self.bands.iter_mut().map(|t| t as &mut dyn Track);
        pitch.chain(notes).chain(classes).chain(bands)
    }

    /// Whether this chain reads the separator's harmonic sum beside its stem (a drum
    /// transcriber's backing, a lead's harmonic view).
    pub(super) fn wants_backing(&self) -> bool {
        self.backing.is_some()
    }

    /// Feeds one block of the stem; `backing`: the separator's bass, vocals and other of
    /// the same span, for a chain that reads their sum ([`StemChain::wants_backing`]).
    pub(super) fn process(&mut self, block: &[f32], backing: Option<[&[f32]; 3]>) {
        self.samples += block.len();
        let t = Instant::now();
        self.buf.clear();
        self.buf.extend_from_slice(block);
        self.denoise.process_inplace(&mut self.buf);
        let side = match (backing, &mut self.backing) {
            (Some([b, v, o]), Some((denoise, buf))) => {
                buf.clear();
                buf.extend(b.iter().zip(v).zip(o).map(|((b, v), o)| b + v + o));
                denoise.process_inplace(buf);
                Some(&buf[..])
            }
            _ => None,
        };
        self.t_denoise += t.elapsed();
        let input = TrackInput {
            stem: &self.buf,
            side,
            pitch: None,
        };
        if let Some(p) = &mut self.pitch {
            let t = Instant::now();
            Track::process(p, &input);
            self.t_pitch += t.elapsed();
        }
        // Note onsets read the pitch track that has just taken the block.
        let input = TrackInput {
            pitch: self.pitch.as_ref(),
            ..input
        };
        if let Some(n) = &mut self.notes {
            let t = Instant::now();
            n.process(&input);
            self.t_notes += t.elapsed();
        }
        if let Some(c) = &mut self.classes {
            let t = Instant::now();
            Track::process(c, &input);
            self.t_classes += t.elapsed();
        }
        for b in &mut self.bands {
            b.process(&input);
        }
    }

    pub(super) fn finish(&mut self) {
        let t = Instant::now();
        let none = TrackInput::stem(&[]);
        if let Some(p) = &mut self.pitch {
            Track::finish(p, &none);
        }
        self.t_pitch += t.elapsed();
        let input = TrackInput {
            pitch: self.pitch.as_ref(),
            ..none
        };
        if let Some(n) = &mut self.notes {
            n.finish(&input);
        }
        if let Some(c) = &mut self.classes {
            let t = Instant::now();
            Track::finish(c, &input);
            self.t_classes += t.elapsed();
        }
        for b in &mut self.bands {
            b.finish(&input);
        }
    }

    /// Input samples after which every feature of the chain is final: its slowest track's
    /// latency after the denoiser's.
    pub(super) fn latency_samples(&self) -> usize {
        self.tracks()
            .map(|t| t.latency_samples())
            .max()
            .unwrap_or(0)
            + self.denoise.latency_samples()
    }

    /// Per-hop and per-bin values the chain holds.
    pub(super) fn retained(&self) -> usize {
        self.tracks().map(|t| t.retained()).sum()
    }

    /// Forgets the first `d` bins of every track and the per-hop records already binned
    /// (see [`Engine::discard_before`]).
    pub(super) fn discard(&mut self, d: usize) {
        self.tracks_mut().for_each(|t| t.discard_before(d));
    }

    pub(super) fn reset(&mut self) {
        self.denoise.reset();
        if let Some((d, _)) = &mut self.backing {
            d.reset();
        }
        self.samples = 0;
        self.tracks_mut().for_each(|t| t.reset());
    }
}

/// Feeds one block to every chain: supplied stems where given, separated ones otherwise.
/// Chains run on their own threads when the block is large enough to pay for it.
pub(super) fn feed(
    chains: &mut [StemChain],
    sep_out: &StemOutput,
    supplied: &[(Stem, &[f32])],
    parallel: bool,
) {
    type Input<'a> = (&'a mut StemChain, &'a [f32], Option<[&'a [f32]; 3]>);
    let inputs: Vec<Input> = chains
        .iter_mut()
        .map(|c| {
            let stem = c.stem;
            let given = supplied.iter().find(|(s, _)| *s == stem).map(|(_, x)| *x);
            let input = given.unwrap_or_else(|| sep_out.get(stem));
            // A separated stem comes with the harmonic sum the separator made beside it
            // when its chain reads that (a drum transcriber's backing, a lead's view).
            let backing = (given.is_none() && c.wants_backing())
                .then(|| {
                    let parts = [Stem::Bass, Stem::Vocals, Stem::Other].map(|s| sep_out.get(s));
                    parts
                        .iter()
                        .all(|p| p.len() == input.len())
                        .then_some(parts)
                })
                .flatten();
            (c, input, backing)
        })
        .collect();
    let big = inputs.iter().map(|(_, x, _)| x.len()).max().unwrap_or(0) >= PARALLEL_MIN_BLOCK;
    if parallel && big && inputs.len() > 1 {
        std::thread::scope(|s| {
            for (c, x, b) in inputs {
                s.spawn(move || c.process(x, b));
            }
        });
    } else {
        for (c, x, b) in inputs {
            c.process(x, b);
        }
    }
}
