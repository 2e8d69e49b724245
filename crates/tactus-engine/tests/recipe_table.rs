//! The recipe table, pinned: every (role, source, profile, separator, pitch choice) and the
//! recipe it gives ([`tactus_engine::recipe::recipe`]), written out, one line each. A change
//! to the table shows here as a changed line; the settings every stem shares are checked
//! once, below the table.

use tactus_engine::profile::Profile;
use tactus_engine::recipe::{recipe, PitchMethod, Role, SeparatorKind, Source};

/// `role source profile separator pitch | range tracker lag [harmonic-view] [advance]
/// [plain-guard CEILING_HZ] [note role] | levels`. Trackers show the settings that differ from the harmonic sum's
/// bass or melody defaults: `h` harmonics, `fr` fundamental ratio, `gate` contour gate (dB),
/// `reg` register weighting (semitones), `rise` and `sal` the attack alignment, `net` the
/// learned network, `blend` its blend with the harmonic sum, `veto` its voicing veto (nats).
/// Levels: `iqr` the fences' IQR floor and `span` the prior span (semitones), `register`
/// (Hz), `held` hops, `shadow` hops, `agree` (semitones), `sure` confidence, quantile and
/// margins. The `mix onnx` rows do not occur (an ONNX separator's stems are clean); they
/// are here because the function is total.
const TABLE: &str = "
bass  clean full spectral auto     | 35-400 Hz shs(bass) lag 10 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full spectral yin      | 35-400 Hz yin lag 10 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full spectral pyin     | 35-400 Hz pyin lag 10 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full spectral shs      | 35-400 Hz shs(bass) lag 10 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full spectral auto-shs | 35-400 Hz shs(bass) lag 10 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full spectral learned  | 35-400 Hz shs(bass net bass blend 0.3) lag 10 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full none     auto     | 35-400 Hz shs(bass) lag 10 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full none     yin      | 35-400 Hz yin lag 10 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full none     pyin     | 35-400 Hz pyin lag 10 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full none     shs      | 35-400 Hz shs(bass) lag 10 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full none     auto-shs | 35-400 Hz shs(bass) lag 10 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full none     learned  | 35-400 Hz shs(bass net bass blend 0.3) lag 10 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full onnx     auto     | 35-400 Hz shs(bass) lag 10 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full onnx     yin      | 35-400 Hz yin lag 10 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full onnx     pyin     | 35-400 Hz pyin lag 10 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full onnx     shs      | 35-400 Hz shs(bass) lag 10 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full onnx     auto-shs | 35-400 Hz shs(bass) lag 10 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean full onnx     learned  | 35-400 Hz shs(bass net bass blend 0.3) lag 10 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live spectral auto     | 41-400 Hz yin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live spectral yin      | 41-400 Hz yin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live spectral pyin     | 41-400 Hz pyin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live spectral shs      | 41-400 Hz shs(bass) lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live spectral auto-shs | 41-400 Hz yin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live spectral learned  | 35-400 Hz shs(bass net bass blend 0.3) lag 0 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live none     auto     | 41-400 Hz yin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live none     yin      | 41-400 Hz yin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live none     pyin     | 41-400 Hz pyin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live none     shs      | 41-400 Hz shs(bass) lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live none     auto-shs | 41-400 Hz yin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live none     learned  | 35-400 Hz shs(bass net bass blend 0.3) lag 0 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live onnx     auto     | 41-400 Hz yin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live onnx     yin      | 41-400 Hz yin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live onnx     pyin     | 41-400 Hz pyin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live onnx     shs      | 41-400 Hz shs(bass) lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live onnx     auto-shs | 41-400 Hz yin lag 2 | iqr 12 span 20 register 41.203-293.66 held 5
bass  clean live onnx     learned  | 35-400 Hz shs(bass net bass blend 0.3) lag 0 plain-guard 400 | iqr 12 span 20 register 41.203-293.66 held 5
bass  mix   full spectral auto     | 35-400 Hz view(bass fr 0.1 reg 12 net bass-harmonic blend 0.3) lag 10 harmonic-view advance 3 plain-guard 400 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25 sure 0.95 q 0.01 -1 +inf
bass  mix   full spectral yin      | 35-400 Hz yin lag 10 advance 3 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full spectral pyin     | 35-400 Hz pyin lag 10 advance 3 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full spectral shs      | 35-400 Hz shs(bass fr 0.1 reg 12) lag 10 advance 3 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full spectral auto-shs | 35-400 Hz shs(bass fr 0.1 reg 12) lag 10 advance 3 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full spectral learned  | 35-400 Hz view(bass fr 0.1 reg 12 net bass-harmonic blend 0.3) lag 10 harmonic-view advance 3 plain-guard 400 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25 sure 0.95 q 0.01 -1 +inf
bass  mix   full none     auto     | 35-400 Hz shs(bass fr 0.1 reg 12) lag 10 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full none     yin      | 35-400 Hz yin lag 10 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full none     pyin     | 35-400 Hz pyin lag 10 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full none     shs      | 35-400 Hz shs(bass fr 0.1 reg 12) lag 10 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full none     auto-shs | 35-400 Hz shs(bass fr 0.1 reg 12) lag 10 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full none     learned  | 35-400 Hz shs(bass fr 0.1 reg 12 net bass blend 0.3) lag 10 plain-guard 400 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25 sure 0.95 q 0.01 -1 +inf
bass  mix   full onnx     auto     | 35-400 Hz shs(bass fr 0.1 reg 12) lag 10 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full onnx     yin      | 35-400 Hz yin lag 10 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full onnx     pyin     | 35-400 Hz pyin lag 10 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full onnx     shs      | 35-400 Hz shs(bass fr 0.1 reg 12) lag 10 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full onnx     auto-shs | 35-400 Hz shs(bass fr 0.1 reg 12) lag 10 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   full onnx     learned  | 35-400 Hz shs(bass fr 0.1 reg 12 net bass blend 0.3) lag 10 plain-guard 400 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25 sure 0.95 q 0.01 -1 +inf
bass  mix   live spectral auto     | 35-400 Hz view(bass fr 0.1 net bass-live veto 2) lag 0 harmonic-view plain-guard 400 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25 sure 0.95 q 0.01 -1 +inf
bass  mix   live spectral yin      | 41-400 Hz yin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live spectral pyin     | 41-400 Hz pyin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live spectral shs      | 41-400 Hz shs(bass fr 0.1 reg 12) lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live spectral auto-shs | 41-400 Hz yin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live spectral learned  | 35-400 Hz view(bass fr 0.1 net bass-live veto 2) lag 0 harmonic-view plain-guard 400 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25 sure 0.95 q 0.01 -1 +inf
bass  mix   live none     auto     | 41-400 Hz yin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live none     yin      | 41-400 Hz yin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live none     pyin     | 41-400 Hz pyin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live none     shs      | 41-400 Hz shs(bass fr 0.1 reg 12) lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live none     auto-shs | 41-400 Hz yin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live none     learned  | 35-400 Hz shs(bass fr 0.1 reg 12 net bass blend 0.3) lag 0 plain-guard 400 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25 sure 0.95 q 0.01 -1 +inf
bass  mix   live onnx     auto     | 41-400 Hz yin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live onnx     yin      | 41-400 Hz yin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live onnx     pyin     | 41-400 Hz pyin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live onnx     shs      | 41-400 Hz shs(bass fr 0.1 reg 12) lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live onnx     auto-shs | 41-400 Hz yin lag 2 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25
bass  mix   live onnx     learned  | 35-400 Hz shs(bass fr 0.1 reg 12 net bass blend 0.3) lag 0 plain-guard 400 plucked-mix | iqr 12 span 20 register 41.203-293.66 held 3 shadow 25 sure 0.95 q 0.01 -1 +inf
lead  clean full spectral auto     | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full spectral yin      | 70-1400 Hz yin lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full spectral pyin     | 70-1400 Hz pyin lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full spectral shs      | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full spectral auto-shs | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full spectral learned  | 70-1400 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 10 plain-guard 2000 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full none     auto     | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full none     yin      | 70-1400 Hz yin lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full none     pyin     | 70-1400 Hz pyin lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full none     shs      | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full none     auto-shs | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full none     learned  | 70-1400 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 10 plain-guard 2000 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full onnx     auto     | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full onnx     yin      | 70-1400 Hz yin lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full onnx     pyin     | 70-1400 Hz pyin lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full onnx     shs      | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full onnx     auto-shs | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean full onnx     learned  | 70-1400 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 10 plain-guard 2000 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live spectral auto     | 70-1400 Hz yin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live spectral yin      | 70-1400 Hz yin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live spectral pyin     | 70-1400 Hz pyin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live spectral shs      | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live spectral auto-shs | 70-1400 Hz yin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live spectral learned  | 70-1400 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 1 plain-guard 2000 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live none     auto     | 70-1400 Hz yin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live none     yin      | 70-1400 Hz yin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live none     pyin     | 70-1400 Hz pyin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live none     shs      | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live none     auto-shs | 70-1400 Hz yin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live none     learned  | 70-1400 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 1 plain-guard 2000 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live onnx     auto     | 70-1400 Hz yin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live onnx     yin      | 70-1400 Hz yin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live onnx     pyin     | 70-1400 Hz pyin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live onnx     shs      | 70-1400 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live onnx     auto-shs | 70-1400 Hz yin lag 2 clean-lead | iqr 4 span 16 register 220-783.99
lead  clean live onnx     learned  | 70-1400 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 1 plain-guard 2000 clean-lead | iqr 4 span 16 register 220-783.99
lead  mix   full spectral auto     | 70-1400 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead-harmonic veto 3) lag 10 harmonic-view advance 3 plain-guard 2000 | iqr 4 span 16 register 220-783.99 held 8 agree 1 sure 0.7 q 0.02 -1 +1
lead  mix   full spectral yin      | 70-1400 Hz yin lag 10 advance 3 | iqr 4 span 16 register 220-783.99
lead  mix   full spectral pyin     | 70-1400 Hz pyin lag 10 advance 3 | iqr 4 span 16 register 220-783.99
lead  mix   full spectral shs      | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 10 advance 3 | iqr 4 span 16 register 220-783.99
lead  mix   full spectral auto-shs | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 10 advance 3 | iqr 4 span 16 register 220-783.99
lead  mix   full spectral learned  | 70-1400 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead-harmonic veto 3) lag 10 harmonic-view advance 3 plain-guard 2000 | iqr 4 span 16 register 220-783.99 held 8 agree 1 sure 0.7 q 0.02 -1 +1
lead  mix   full none     auto     | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 10 | iqr 4 span 16 register 220-783.99
lead  mix   full none     yin      | 70-1400 Hz yin lag 10 | iqr 4 span 16 register 220-783.99
lead  mix   full none     pyin     | 70-1400 Hz pyin lag 10 | iqr 4 span 16 register 220-783.99
lead  mix   full none     shs      | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 10 | iqr 4 span 16 register 220-783.99
lead  mix   full none     auto-shs | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 10 | iqr 4 span 16 register 220-783.99
lead  mix   full none     learned  | 70-1400 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead veto 3) lag 10 plain-guard 2000 | iqr 4 span 16 register 220-783.99 held 8 agree 1 sure 0.7 q 0.02 -1 +1
lead  mix   full onnx     auto     | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 10 | iqr 4 span 16 register 220-783.99
lead  mix   full onnx     yin      | 70-1400 Hz yin lag 10 | iqr 4 span 16 register 220-783.99
lead  mix   full onnx     pyin     | 70-1400 Hz pyin lag 10 | iqr 4 span 16 register 220-783.99
lead  mix   full onnx     shs      | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 10 | iqr 4 span 16 register 220-783.99
lead  mix   full onnx     auto-shs | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 10 | iqr 4 span 16 register 220-783.99
lead  mix   full onnx     learned  | 70-1400 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead veto 3) lag 10 plain-guard 2000 | iqr 4 span 16 register 220-783.99 held 8 agree 1 sure 0.7 q 0.02 -1 +1
lead  mix   live spectral auto     | 70-1400 Hz view(melody fr 0.1 net lead-live veto 2) lag 1 harmonic-view plain-guard 2000 | iqr 4 span 16 register 220-783.99 held 8 sure 0.7 q 0.02 -1 +1
lead  mix   live spectral yin      | 70-1400 Hz yin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live spectral pyin     | 70-1400 Hz pyin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live spectral shs      | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live spectral auto-shs | 70-1400 Hz yin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live spectral learned  | 70-1400 Hz view(melody fr 0.1 net lead-live veto 2) lag 1 harmonic-view plain-guard 2000 | iqr 4 span 16 register 220-783.99 held 8 sure 0.7 q 0.02 -1 +1
lead  mix   live none     auto     | 70-1400 Hz yin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live none     yin      | 70-1400 Hz yin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live none     pyin     | 70-1400 Hz pyin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live none     shs      | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live none     auto-shs | 70-1400 Hz yin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live none     learned  | 70-1400 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead veto 3) lag 1 plain-guard 2000 | iqr 4 span 16 register 220-783.99 held 8 agree 1 sure 0.7 q 0.02 -1 +1
lead  mix   live onnx     auto     | 70-1400 Hz yin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live onnx     yin      | 70-1400 Hz yin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live onnx     pyin     | 70-1400 Hz pyin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live onnx     shs      | 70-1400 Hz shs(melody fr 0.1 gate 6) lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live onnx     auto-shs | 70-1400 Hz yin lag 2 | iqr 4 span 16 register 220-783.99
lead  mix   live onnx     learned  | 70-1400 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead veto 3) lag 1 plain-guard 2000 | iqr 4 span 16 register 220-783.99 held 8 agree 1 sure 0.7 q 0.02 -1 +1
other clean full spectral auto     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other clean full spectral yin      | 50-2000 Hz yin lag 10 | iqr 4 span 16
other clean full spectral pyin     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other clean full spectral shs      | 50-2000 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 | iqr 4 span 16
other clean full spectral auto-shs | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other clean full spectral learned  | 50-2000 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 10 plain-guard 2000 | iqr 4 span 16
other clean full none     auto     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other clean full none     yin      | 50-2000 Hz yin lag 10 | iqr 4 span 16
other clean full none     pyin     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other clean full none     shs      | 50-2000 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 | iqr 4 span 16
other clean full none     auto-shs | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other clean full none     learned  | 50-2000 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 10 plain-guard 2000 | iqr 4 span 16
other clean full onnx     auto     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other clean full onnx     yin      | 50-2000 Hz yin lag 10 | iqr 4 span 16
other clean full onnx     pyin     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other clean full onnx     shs      | 50-2000 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 10 | iqr 4 span 16
other clean full onnx     auto-shs | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other clean full onnx     learned  | 50-2000 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 10 plain-guard 2000 | iqr 4 span 16
other clean live spectral auto     | 50-2000 Hz yin lag 2 | iqr 4 span 16
other clean live spectral yin      | 50-2000 Hz yin lag 2 | iqr 4 span 16
other clean live spectral pyin     | 50-2000 Hz pyin lag 2 | iqr 4 span 16
other clean live spectral shs      | 50-2000 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 2 | iqr 4 span 16
other clean live spectral auto-shs | 50-2000 Hz yin lag 2 | iqr 4 span 16
other clean live spectral learned  | 50-2000 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 1 plain-guard 2000 | iqr 4 span 16
other clean live none     auto     | 50-2000 Hz yin lag 2 | iqr 4 span 16
other clean live none     yin      | 50-2000 Hz yin lag 2 | iqr 4 span 16
other clean live none     pyin     | 50-2000 Hz pyin lag 2 | iqr 4 span 16
other clean live none     shs      | 50-2000 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 2 | iqr 4 span 16
other clean live none     auto-shs | 50-2000 Hz yin lag 2 | iqr 4 span 16
other clean live none     learned  | 50-2000 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 1 plain-guard 2000 | iqr 4 span 16
other clean live onnx     auto     | 50-2000 Hz yin lag 2 | iqr 4 span 16
other clean live onnx     yin      | 50-2000 Hz yin lag 2 | iqr 4 span 16
other clean live onnx     pyin     | 50-2000 Hz pyin lag 2 | iqr 4 span 16
other clean live onnx     shs      | 50-2000 Hz aligned(melody h 12 rise 0.5 sal 0.3) lag 2 | iqr 4 span 16
other clean live onnx     auto-shs | 50-2000 Hz yin lag 2 | iqr 4 span 16
other clean live onnx     learned  | 50-2000 Hz pair(melody h 12 rise 0.5 sal 0.3 / melody h 12 rise 0.5 sal 0.3 net lead veto 3) lag 1 plain-guard 2000 | iqr 4 span 16
other mix   full spectral auto     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other mix   full spectral yin      | 50-2000 Hz yin lag 10 | iqr 4 span 16
other mix   full spectral pyin     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other mix   full spectral shs      | 50-2000 Hz shs(melody fr 0.1 gate 6) lag 10 | iqr 4 span 16
other mix   full spectral auto-shs | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other mix   full spectral learned  | 50-2000 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead veto 3) lag 10 plain-guard 2000 | iqr 4 span 16 held 8 agree 1 sure 0.7 q 0.02 -1 +1
other mix   full none     auto     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other mix   full none     yin      | 50-2000 Hz yin lag 10 | iqr 4 span 16
other mix   full none     pyin     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other mix   full none     shs      | 50-2000 Hz shs(melody fr 0.1 gate 6) lag 10 | iqr 4 span 16
other mix   full none     auto-shs | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other mix   full none     learned  | 50-2000 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead veto 3) lag 10 plain-guard 2000 | iqr 4 span 16 held 8 agree 1 sure 0.7 q 0.02 -1 +1
other mix   full onnx     auto     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other mix   full onnx     yin      | 50-2000 Hz yin lag 10 | iqr 4 span 16
other mix   full onnx     pyin     | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other mix   full onnx     shs      | 50-2000 Hz shs(melody fr 0.1 gate 6) lag 10 | iqr 4 span 16
other mix   full onnx     auto-shs | 50-2000 Hz pyin lag 10 | iqr 4 span 16
other mix   full onnx     learned  | 50-2000 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead veto 3) lag 10 plain-guard 2000 | iqr 4 span 16 held 8 agree 1 sure 0.7 q 0.02 -1 +1
other mix   live spectral auto     | 50-2000 Hz yin lag 2 | iqr 4 span 16
other mix   live spectral yin      | 50-2000 Hz yin lag 2 | iqr 4 span 16
other mix   live spectral pyin     | 50-2000 Hz pyin lag 2 | iqr 4 span 16
other mix   live spectral shs      | 50-2000 Hz shs(melody fr 0.1 gate 6) lag 2 | iqr 4 span 16
other mix   live spectral auto-shs | 50-2000 Hz yin lag 2 | iqr 4 span 16
other mix   live spectral learned  | 50-2000 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead veto 3) lag 1 plain-guard 2000 | iqr 4 span 16 held 8 agree 1 sure 0.7 q 0.02 -1 +1
other mix   live none     auto     | 50-2000 Hz yin lag 2 | iqr 4 span 16
other mix   live none     yin      | 50-2000 Hz yin lag 2 | iqr 4 span 16
other mix   live none     pyin     | 50-2000 Hz pyin lag 2 | iqr 4 span 16
other mix   live none     shs      | 50-2000 Hz shs(melody fr 0.1 gate 6) lag 2 | iqr 4 span 16
other mix   live none     auto-shs | 50-2000 Hz yin lag 2 | iqr 4 span 16
other mix   live none     learned  | 50-2000 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead veto 3) lag 1 plain-guard 2000 | iqr 4 span 16 held 8 agree 1 sure 0.7 q 0.02 -1 +1
other mix   live onnx     auto     | 50-2000 Hz yin lag 2 | iqr 4 span 16
other mix   live onnx     yin      | 50-2000 Hz yin lag 2 | iqr 4 span 16
other mix   live onnx     pyin     | 50-2000 Hz pyin lag 2 | iqr 4 span 16
other mix   live onnx     shs      | 50-2000 Hz shs(melody fr 0.1 gate 6) lag 2 | iqr 4 span 16
other mix   live onnx     auto-shs | 50-2000 Hz yin lag 2 | iqr 4 span 16
other mix   live onnx     learned  | 50-2000 Hz pair(melody fr 0.1 gate 6 / melody fr 0.1 net lead veto 3) lag 1 plain-guard 2000 | iqr 4 span 16 held 8 agree 1 sure 0.7 q 0.02 -1 +1
";

fn rows() -> Vec<String> {
    let mut out = Vec::new();
    for role in Role::ALL {
        for source in Source::ALL {
            for profile in [Profile::Full, Profile::Live] {
                for sep in SeparatorKind::ALL {
                    for pitch in PitchMethod::ALL {
                        let r = recipe(role, source, profile, sep, pitch);
                        out.push(format!(
                            "{:<5} {:<5} {:<4} {:<8} {:<8} | {r}",
                            role.name(),
                            source.name(),
                            profile.name(),
                            sep.name(),
                            pitch.name()
                        ));
                    }
                }
            }
        }
    }
    out
}

#[test]
fn every_combination_gives_the_recipe_written_here() {
    let got = rows();
    let want: Vec<&str> = TABLE.lines().filter(|l| !l.trim().is_empty()).collect();
    let differ: Vec<String> = got
        .iter()
        .zip(&want)
        .filter(|(g, w)| g != w)
        .map(|(g, w)| format!("  want {w}\n  got  {g}"))
        .collect();
    assert!(
        differ.is_empty() && got.len() == want.len(),
        "{} of {} lines differ ({} rows, {} written):\n{}\n\nthe whole table:\n{}",
        differ.len(),
        got.len(),
        got.len(),
        want.len(),
        differ.join("\n"),
        got.join("\n")
    );
}

#[test]
fn every_recipe_shares_the_level_range_constants() {
    for role in Role::ALL {
        for source in Source::ALL {
            for profile in [Profile::Full, Profile::Live] {
                for sep in SeparatorKind::ALL {
                    for pitch in PitchMethod::ALL {
                        let l = recipe(role, source, profile, sep, pitch).levels;
                        assert_eq!(
                            (
                                l.quantile,
                                l.held_tol_st,
                                l.held_min_share,
                                l.held_min_hops,
                                l.prior_fade_hops,
                                l.register_fade_hops
                            ),
                            (0.01, 1.0, 0.25, 300, 3000.0, 200.0)
                        );
                    }
                }
            }
        }
    }
}
