#!/usr/bin/env python3
"""Export Demucs v4 `htdemucs` (MIT, Meta) to ONNX with the STFT and iSTFT OUTSIDE the graph.

Run this where you have internet access (the pre-trained weights are downloaded by Demucs):

    python3 -m venv .venv-demucs && . .venv-demucs/bin/activate
    pip install demucs onnx            # pulls torch; CPU wheels are enough
    python models/export_htdemucs.py                      # pre-trained -> models/htdemucs.onnx
    python models/export_htdemucs.py --random-weights     # same size, random (benchmarks)
    python models/export_htdemucs.py --tiny --golden DIR  # a few-MB model + golden fixtures

Graph contract (what tactus-separate's HtDemucsSeparator feeds and reads), opset 17:

  input  `mix`  float32 [1, 2, 343980]        one 7.8 s stereo segment at 44.1 kHz
  input  `mag`  float32 [1, 4, 2048, 336]     Demucs's `_spec(mix)` as real/imag channels
                                              [L.re, L.im, R.re, R.im] (`cac=True`)
  output `freq` float32 [1, 4, 4, 2048, 336]  per source, the frequency branch's complex
                                              spectrogram, channels as in `mag`
  output `time` float32 [1, 4, 2, 343980]     per source, the time branch's waveform
  sources, in order: drums, bass, other, vocals

  stem = Demucs `_ispec(freq)` + time. `_spec` = reflect-pad 1536 samples before and
  1536 + (336*1024 - 343980) after, `torch.stft(n_fft=4096, hop=1024, periodic Hann,
  normalized=True, center=True, pad_mode="reflect")`, drop the Nyquist bin, keep frames
  2..338. `_ispec` = add a zero Nyquist bin and two zero frames at each end,
  `torch.istft(normalized=True, center=True, length=336*1024 + 3072)`, crop 1536 samples
  at the start to 343980 samples. The Rust side does both (crate::onnx::htdemucs).

What happens between `_spec` and `_ispec` is HTDemucs.forward() unchanged (normalisation,
both encoders, the cross-transformer, both decoders, de-normalisation); `core_forward`
below calls the model's own modules in the same order.

--golden DIR copies the exported model there and writes `stems_mono.txt`: Demucs's own
model(mix) (the full forward, STFT and iSTFT in torch) for a deterministic test signal
that the Rust test recomputes, mono per source, at ~6000 sample positions (edges
included). The Rust test checks its STFT, the graph call and its iSTFT + sum against it
to 1e-4 without torch.
"""

import argparse
import json
import math
import os
import sys
import time
from fractions import Fraction

SOURCES = ["drums", "bass", "other", "vocals"]
SAMPLE_RATE = 44100
SEGMENT = Fraction(39, 5)  # 7.8 s, htdemucs's training segment
LENGTH = int(SEGMENT * SAMPLE_RATE)  # 343980
FRAMES = math.ceil(LENGTH / 1024)  # 336


def build_model(args):
    import torch
    from demucs.htdemucs import HTDemucs

    if args.tiny:
        torch.manual_seed(0)
        # Same I/O layout (nfft 4096, depth 4, cac, 4 sources, 7.8 s), few channels.
        model = HTDemucs(sources=SOURCES, samplerate=SAMPLE_RATE, segment=SEGMENT,
                         channels=8, t_layers=1, t_heads=2, bottom_channels=0)
    elif args.random_weights:
        torch.manual_seed(0)
        # htdemucs's published hyper-parameters, random weights (same size and speed).
        model = HTDemucs(sources=SOURCES, samplerate=SAMPLE_RATE, segment=SEGMENT,
                         channels=48, bottom_channels=512, t_layers=5)
    else:
        from demucs.pretrained import get_model
        bag = get_model("htdemucs")
        model = bag.models[0] if hasattr(bag, "models") else bag
    model.eval()
    assert list(model.sources) == SOURCES, model.sources
    assert model.nfft == 4096 and model.hop_length == 1024 and model.cac
    return model


class Core:
    """HTDemucs.forward() between `_spec`/`_magnitude` and `_mask`/`_ispec`."""

    @staticmethod
    def make(model):
        import torch
        from einops import rearrange

        class _Core(torch.nn.Module):
            def __init__(self, m):
                super().__init__()
                self.m = m

            def forward(self, mix, mag):
                m = self.m
                x = mag
                B, C, Fq, T = x.shape
                mean = x.mean(dim=(1, 2, 3), keepdim=True)
                std = x.std(dim=(1, 2, 3), keepdim=True)
                x = (x - mean) / (1e-5 + std)
                xt = mix
                meant = xt.mean(dim=(1, 2), keepdim=True)
                stdt = xt.std(dim=(1, 2), keepdim=True)
                xt = (xt - meant) / (1e-5 + stdt)
                saved, saved_t, lengths, lengths_t = [], [], [], []
                for idx, encode in enumerate(m.encoder):
                    lengths.append(x.shape[-1])
                    inject = None
                    if idx < len(m.tencoder):
                        lengths_t.append(xt.shape[-1])
                        tenc = m.tencoder[idx]
                        xt = tenc(xt)
                        if not tenc.empty:
                            saved_t.append(xt)
                        else:
                            inject = xt
                    x = encode(x, inject)
                    if idx == 0 and m.freq_emb is not None:
                        frs = torch.arange(x.shape[-2], device=x.device)
                        emb = m.freq_emb(frs).t()[None, :, :, None].expand_as(x)
                        x = x + m.freq_emb_scale * emb
                    saved.append(x)
                if m.crosstransformer:
                    if m.bottom_channels:
                        _, _, f, _ = x.shape
                        x = rearrange(x, "b c f t-> b c (f t)")
                        x = m.channel_upsampler(x)
                        x = rearrange(x, "b c (f t)-> b c f t", f=f)
                        xt = m.channel_upsampler_t(xt)
                    x, xt = m.crosstransformer(x, xt)
                    if m.bottom_channels:
                        x = rearrange(x, "b c f t-> b c (f t)")
                        x = m.channel_downsampler(x)
                        x = rearrange(x, "b c (f t)-> b c f t", f=f)
                        xt = m.channel_downsampler_t(xt)
                for idx, decode in enumerate(m.decoder):
                    skip = saved.pop(-1)
                    x, pre = decode(x, skip, lengths.pop(-1))
                    offset = m.depth - len(m.tdecoder)
                    if idx >= offset:
                        tdec = m.tdecoder[idx - offset]
                        length_t = lengths_t.pop(-1)
                        if tdec.empty:
                            pre = pre[:, :, 0]
                            xt, _ = tdec(pre, None, length_t)
                        else:
                            skip = saved_t.pop(-1)
                            xt, _ = tdec(xt, skip, length_t)
                S = len(m.sources)
                x = x.view(B, S, -1, Fq, T)
                x = x * std[:, None] + mean[:, None]
                xt = xt.view(B, S, -1, mix.shape[-1])
                xt = xt * stdt[:, None] + meant[:, None]
                return x, xt

        return _Core(model)


def spec_and_mag(model, mix):
    z = model._spec(mix)
    return z, model._magnitude(z)


def export(model, out, opset=17):
    import torch

    core = Core.make(model).eval()
    # nn.MultiheadAttention's eval-mode fast path (aten::_native_multi_head_attention)
    # has no ONNX export; the regular path computes the same thing.
    if hasattr(torch.backends, "mha"):
        torch.backends.mha.set_fastpath_enabled(False)
    mix = torch.randn(1, 2, LENGTH) * 0.1
    _, mag = spec_and_mag(model, mix)
    assert list(mag.shape) == [1, 4, 2048, FRAMES], mag.shape
    with torch.no_grad():
        torch.onnx.export(core, (mix, mag), out, input_names=["mix", "mag"],
                          output_names=["freq", "time"], opset_version=opset,
                          do_constant_folding=True, dynamo=False)
    return core


def check_parity(model, core, out):
    """The exported graph + Demucs's own _spec/_ispec equals model.forward()."""
    import numpy as np
    import onnxruntime as ort
    import torch

    mix = torch.randn(1, 2, LENGTH) * 0.1
    with torch.no_grad():
        ref = model(mix)
        z, mag = spec_and_mag(model, mix)
        sess = ort.InferenceSession(out, providers=["CPUExecutionProvider"])
        t0 = time.perf_counter()
        freq, tim = sess.run(None, {"mix": mix.numpy(), "mag": mag.numpy()})
        dt = time.perf_counter() - t0
        zout = model._mask(z, torch.from_numpy(freq))
        got = model._ispec(zout, LENGTH) + torch.from_numpy(tim)
    err = float((got - ref).abs().max() / ref.abs().max())
    print(f"parity: max |onnx path - forward()| / max|forward()| = {err:.2e}; "
          f"one segment {dt:.2f} s")
    assert err < 1e-4, err


def golden_input():
    """The golden test signal; crates/tactus-separate/tests/onnx_htdemucs.rs computes
    the same samples (f64 arithmetic, then f32)."""
    import numpy as np

    state = 12345
    tau = 2 * math.pi
    left = np.empty(LENGTH, np.float32)
    right = np.empty(LENGTH, np.float32)
    for i in range(LENGTH):
        t = i / SAMPLE_RATE
        state = (state * 1664525 + 1013904223) % (1 << 32)
        nl = (state >> 8) / float(1 << 24) * 2 - 1
        state = (state * 1664525 + 1013904223) % (1 << 32)
        nr = (state >> 8) / float(1 << 24) * 2 - 1
        left[i] = 0.3 * math.sin(tau * 220 * t) + 0.1 * math.sin(tau * 1234.5 * t + 0.3) + 0.05 * nl
        right[i] = 0.2 * math.sin(tau * 330 * t + 1) + 0.1 * math.sin(tau * 87 * t) + 0.05 * nr
    return np.stack([left, right])[None]


def write_golden(model, out, golden_dir, points=6000):
    """Small golden fixtures: the model, and Demucs's own model(mix) (mono per source) at
    `points` random sample positions, as `index value` lines (index = source * LENGTH + i)."""
    import shutil

    import numpy as np
    import torch

    os.makedirs(golden_dir, exist_ok=True)
    mix = torch.from_numpy(golden_input())
    with torch.no_grad():
        stems = model(mix)[0].numpy()  # [4, 2, LENGTH]
    mono = 0.5 * (stems[:, 0] + stems[:, 1])
    # The same path with the exported graph in ONNX Runtime (what Rust runs): Demucs's
    # _spec -> graph -> Demucs's _ispec + time. Isolates the Rust STFT/iSTFT from the
    # float differences between torch and ONNX Runtime inside the network.
    import onnxruntime as ort

    with torch.no_grad():
        z, mag = spec_and_mag(model, mix)
        sess = ort.InferenceSession(out, providers=["CPUExecutionProvider"])
        freq, tim = sess.run(None, {"mix": mix.numpy(), "mag": mag.numpy()})
        via = (model._ispec(model._mask(z, torch.from_numpy(freq)), LENGTH)
               + torch.from_numpy(tim))[0].numpy()
    mono_ort = 0.5 * (via[:, 0] + via[:, 1])
    rng = np.random.default_rng(3)
    idx = np.sort(rng.choice(4 * LENGTH, size=points, replace=False))
    # Include both segment edges of every source, where the framing matters most.
    edges = [s * LENGTH + i for s in range(4) for i in (0, 1, 2, 1535, 1536, 2047,
                                                          LENGTH - 2049, LENGTH - 2, LENGTH - 1)]
    idx = np.unique(np.concatenate([idx, edges]))
    for name, what, arr in [("stems_mono.txt", "model(mix)", mono),
                            ("stems_mono_ort.txt", "_ispec(onnx freq) + onnx time", mono_ort)]:
        flat = arr.reshape(-1)
        with open(os.path.join(golden_dir, name), "w") as f:
            f.write(f"# Demucs {model.__class__.__name__} (tiny, seed 0) {what}, mono per source,\n"
                    f"# index = source * {LENGTH} + sample; sources {SOURCES}\n")
            for i in idx:
                f.write(f"{int(i)} {float(flat[i]):.9g}\n")
    if os.path.abspath(os.path.dirname(out)) != os.path.abspath(golden_dir):
        shutil.copy(out, os.path.join(golden_dir, os.path.basename(out)))
    print(f"golden fixtures in {golden_dir} ({len(idx)} points)")


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--random-weights", action="store_true")
    g.add_argument("--tiny", action="store_true")
    ap.add_argument("--out")
    ap.add_argument("--golden", help="directory for golden fixtures (use with --tiny)")
    ap.add_argument("--no-check", action="store_true")
    a = ap.parse_args()
    name = ("htdemucs-tiny.onnx" if a.tiny else
            "htdemucs-random.onnx" if a.random_weights else "htdemucs.onnx")
    out = a.out or os.path.join(here, name)
    t0 = time.perf_counter()
    model = build_model(a)
    core = export(model, out)
    print(f"wrote {out}: {os.path.getsize(out) / 1e6:.1f} MB in {time.perf_counter() - t0:.0f} s")
    if not a.no_check:
        check_parity(model, core, out)
    if a.golden:
        write_golden(model, out, a.golden)


if __name__ == "__main__":
    sys.exit(main())
