//! Bass-line and lead-melody tracking for mixtures: harmonic-sum (subharmonic summation)
//! salience with fixed-lag Viterbi over the candidates.
//!
//! After Hermes, "Measurement of pitch by subharmonic summation", JASA 83(1), 1988 (the
//! salience), Klapuri, "Multiple fundamental frequency estimation by summing harmonic
//! amplitudes", ISMIR 2006 (the max over each harmonic's neighbourhood, decaying weights)
//! and Goto, "A real-time music-scene-description system: predominant-F0 estimation for
//! detecting melody and bass lines in real-world audio signals", Speech Communication 43(4),
//! 2004 (a bass line is the lowest strong harmonic source, tracked with continuity). The
//! Viterbi is pYIN's idea ([`crate::pyin`]): the pitch of a frame is decided together with its
//! neighbours, with a fixed lag when streaming.
//!
//! ## Algorithm (per hop)
//! 1. **Spectrum.** The frame (`frame` samples centred on the hop, see [`Framer`]) minus its
//!    mean, scaled to unit peak, times a Hann window, zero-padded to `n_fft`, real FFT;
//!    `A_k = |X_k|^compress`.
//! 2. **Salience** of each candidate f0 on a log grid (`bins_per_semitone` per semitone over
//!    `[fmin, fmax]`):
//!    `S(f) = tilt(f) · Σ_{h=1..H, h·f ≤ max_harmonic_hz} w^{h−1} · max_{k ∈ K(h·f)} A_k`, where
//!    `K(x)` are the FFT bins within ± `harmonic_width_st` semitones of `x` (below Nyquist),
//!    `w` = `harmonic_decay` and `tilt(f) = (f / fmin)^(−low_tilt)` can favour the lowest of
//!    several harmonic sources (off by default: it pulls plucked basses an octave down).
//!    Decaying weights make `f` beat both `f/2` (which only collects every other harmonic)
//!    and `2f`.
//! 3. **Observation.** Voiced candidate `c`: `log(V · p_c)` with
//!    `p_c = (S_c / max S)^γ` (γ = `sharpness`); unvoiced: `log(1 − V)`. The voicing evidence
//!    `V = σ((ln(peak / floor) − ln r0) / 0.5)` compares the best harmonic sum with what noise
//!    of the same spectrum level would give (`floor` = mean `A_k` over the searched band times
//!    `Σ w^{h−1}`), clamped to `[0.02, 0.98]`; a silent frame has `V = 0.02`.
//! 4. **HMM** with `M` voiced states (the candidates) and one unvoiced state. Voiced → voiced:
//!    triangular weights over `±max_jump_bins`, 1 for staying (peak-normalised, so that the
//!    voiced layer pays nothing for having a pitch that the unvoiced state lacks), times
//!    `1 − switch_prob`; voiced ↔ unvoiced (into any bin): `switch_prob`.
//! 5. **Decoding**: Viterbi in the log domain, O(M · (2·max_jump_bins + 1)) per hop, with a
//!    fixed lag: once hop `t` is observed, hop `t − lag_hops` is decided by backtracking from
//!    the best current state (exactly offline Viterbi when `lag_hops ≥` the track's hops).
//! 6. **Output.** A voiced hop reports the candidate's f0 refined by a parabola through the
//!    salience of the decided candidate and its neighbours (the grid is 1/`bins_per_semitone`
//!    of a semitone).
//! 7. **Contour voicing** (`contour_gate_db` > 0; after Salamon & Gómez, "Melody extraction
//!    from polyphonic music signals using pitch contour characteristics", IEEE TASLP 20(6),
//!    2012, where contours whose mean salience falls well below the track's are dropped).
//!    A *contour* is a run of decoded voiced, non-silent hops whose bins move by at most
//!    `contour_jump_bins` from hop to hop. Its level at hop `h` is
//!    `L_h = 20·log10(S_h(c_h) · peak_h)`, the harmonic sum of the decoded candidate in the
//!    input's units (`peak_h` undoes the frame's normalisation). When hop `h` is decided
//!    (at hop `t = h + lag_hops`), its contour's mean level is taken over the contour's
//!    emitted hops up to `h` and, along the provisional path backtracked from the best
//!    state at `t`, its hops after `h` up to `t` (so no latency is added; offline, where
//!    the whole track is decoded at the end, this is the whole contour). The reference is
//!    the running mean of `L` over the emitted voiced hops, `R ← R + w·(L_h − R)` with
//!    `w = max(1/n, hop / contour_ref_s)` (the plain mean for the first `contour_ref_s`
//!    seconds). The hop is reported unvoiced when the contour mean is below
//!    `R − contour_gate_db`. Off by default; the engine turns it on (6 dB) for the lead on a
//!    band of the mix, where the chords left in the vocals band keep a pitch through the
//!    lead's rests.
//! 8. **Register prior** (`register_sigma_st` > 0). A bass line keeps to its register, while
//!    a drum's body or a chord's common subharmonic pulls single hops an octave or a fifth
//!    under it. Once `register_min_hops` voiced hops have been decided, every voiced
//!    candidate's observation gets `−(c − μ)² / (2σ²)` (bins; σ = `register_sigma_st` ×
//!    `bins_per_semitone`), where `μ` is the running mean of the decided voiced bins,
//!    `μ ← μ + w·(c_h − μ)` with `w = max(1/n, hop / register_s)`: a hop observed at `t`
//!    sees the decisions up to `t − lag_hops − 1`, so the prior is causal and adds no
//!    latency (and a decoder whose lag covers the whole track never applies it). Off by
//!    default; the engine turns it on (σ = 12 semitones) for the bass of a mix, where on
//!    the tuning songs it moved bass RPA from 0.80 / 0.85 / 0.89 to 0.82 / 0.89 / 0.90
//!    (sung, chorales, timgm mixes; `benches/bass_eval.py`).
//! 9. **Attack alignment** (`attack_rise_db` > 0, harmonic sum only). A soundfont's lead or
//!    choir patch holds the old note's release over the new note's slow attack, so the decoded
//!    change comes 50–150 ms after the note starts
//!    (`docs/decisions/0035-clean-lead-note-changes-at-the-attack.md`). When hop `h` is decided
//!    (at `t = h + lag_hops`) as a voiced note `A`, the provisional path backtracked from the
//!    best state at `t` is read for the hops after `h`: if it leaves `A` for a note `B` in one
//!    step of at least a semitone, every hop up to that jump voiced and sounding, `B` held for
//!    [`ATTACK_HOLD_HOPS`] hops (within a bin), and the frame's band level (the mean power over
//!    the searched band, in dB of the input's units) rises from `h` to the jump by at least
//!    `attack_rise_db` in all and falls by no more than that from one hop to the next, hop `h`
//!    reports `B` (refined on its own salience). A cross-fade between two sung notes need not
//!    raise the band level, so with `attack_salience_ratio` = r > 0 hop `h` also reports `B`
//!    (same jump and hold) when `B` already sounds there, its salience (the largest within a
//!    bin of `B`) at least r times `A`'s at `h`, and it grows towards the jump, falling by no
//!    more than [`ATTACK_SALIENCE_TOL`] from one hop to the next; the band level's fall then
//!    does not end the search. The decoded state still drives everything else (contour voicing,
//!    register, the Viterbi), and [`WithDecoded`] gives both. No latency is added: only
//!    the lag is read. Off by default; the engine turns it on (0.5 dB, r = 0.3) for a lead that
//!    comes as its own stem.
//!
//! ## Defaults ([`ShsConfig::new`])
//! Range 35–400 Hz (the bass stem of docs/design.md); hop 10 ms; frame = the power of two nearest
//! 200 ms (1024 samples at the bass chain's 4.9 kHz: a 3 Hz semitone at 50 Hz needs the
//! length); `n_fft` = 2 × frame (4 × gains nothing measurable and costs about 4 % more CPU per render);
//! H = 6 harmonics, w = 0.8, each searched ± 1/4 semitone,
//! **only harmonics below 320 Hz** (the spectral separator's bass band ends there, so an
//! isolated stem and a separated one look alike; with the whole band a bassoon's formant
//! pulls the sum to its 2nd and 3rd harmonics: isolated-stem RPA 0.60 instead of 0.96 on the
//! tuned songs); no low tilt, no compression; 3 bins per semitone, γ = 2, r0 = 3, max jump
//! 36 bins (an octave), switch probability 0.02, lag 10 hops. Tuned on 4 chorales of the
//! corpus (`benches/bass_eval.py`), never on the held-out songs.
//!
//! ## Melody defaults ([`ShsConfig::melody`])
//! For the lead (the vocals stem, 70–1400 Hz): frame = the power of two nearest 70 ms (1024
//! samples at the vocal chain's 14.7 kHz: vibrato and sung glides move within 200 ms);
//! H = 8 harmonics up to 5 kHz (a voice's or a lead synth's upper harmonics are what
//! separate it from the chords under it), each searched ± 0.15 semitone; r0 = 6 (chords sound
//! between the lead's phrases, so voicing needs a clearer peak). Everything else as for the
//! bass. Chosen on the drum corpus's `timgm` mixes and the chorales' mono mixes against pYIN
//! (vocals RPA on the mix 0.56 → 0.86 and 0.35 → 0.77; on isolated stems 0.90 → 0.94 and
//! 0.87 → 0.91), never on the held-out families.
//!
//! ## Learned salience
//! With [`ShsConfig::learned`] the Viterbi decodes a network's log-probabilities of the
//! candidates and of "no pitch" ([`crate::bassnet`]) instead of the harmonic sum's (blended
//! with it by [`ShsConfig::learned_blend`]). Its estimates say how sure the network is of the
//! decided pitch: a voiced hop's `aperiodicity` is `1 − Σ p` over the network's probabilities
//! of the candidates within [`CONFIDENCE_BINS`] of the decided one (2 bins: ⅔ semitone), its
//! `voiced_prob` the network's `1 − p(no pitch)`. (The harmonic sum's estimates keep
//! `aperiodicity = 1 − voiced_prob`.) The engine narrows a mixture's lead's and bass's level
//! ranges to the hops it is sure of ([`crate::discretize`] module docs, "Narrowed to the sure
//! hops").
//!
//! ## Latency
//! `frame − frame / 2` (the framer) + `lag_hops × hop` samples, stated by
//! [`HopStage::latency_samples`] and checked against a step in the tests.
//! The contour voicing adds nothing: it looks ahead only along the Viterbi's own lag; the
//! register prior looks only back.
//!
//! No allocation after [`Shs::new`]: FFT plan, scratch, the harmonic-bin table, the Viterbi
//! scores and a ring of `lag_hops + 1` hops of backpointers and salience are allocated up
//! front.
//!
//! [`Framer`]: crate::framer::Framer
//! [`HopStage::latency_samples`]: crate::HopStage::latency_samples

mod attack;
mod config;
mod contour;
mod hmm;
mod hops;
mod net;
mod register;
mod salience;
mod stage;
mod tracker;

pub use attack::{ATTACK_HOLD_HOPS, ATTACK_SALIENCE_TOL};
pub use config::ShsConfig;
pub use stage::{Shs, WithDecoded};
pub use tracker::CONFIDENCE_BINS;

/// Floor for probabilities before the logarithm.
const P_FLOOR: f32 = 1e-30;

/// Band level of a silent frame, dB.
const SILENT_DB: f32 = -240.0;
