"use strict";
(function () {
  const D = JSON.parse(document.getElementById("tactus-data").textContent);
  const binS = D.bin_ms / 1000;
  const frames = D.frames.map(function (h) {
    const b = new Uint8Array(10);
    for (let i = 0; i < 10; i++) b[i] = parseInt(h.substr(2 * i, 2), 16);
    return b;
  });
  const FINGERS = ["thumb", "index", "middle", "ring", "pinky"];
  const glove = document.getElementById("glove");
  const status = document.getElementById("status");
  const note = document.getElementById("note");
  const timeEl = document.getElementById("time");
  const seekEl = document.getElementById("seek");
  const btn = document.getElementById("playbtn");
  const audio = document.getElementById("audio");
  // dots[cell][bit] for cell = finger * 2 + c, bit = dot - 1; cellEls[cell].
  const dots = [], cellEls = [];
  for (let k = 0; k < 10; k++) dots.push(new Array(8));
  document.querySelectorAll(".dot").forEach(function (el) {
    const k = FINGERS.indexOf(el.dataset.finger) * 2 + Number(el.dataset.cell);
    dots[k][Number(el.dataset.dot) - 1] = el;
    cellEls[k] = el.parentNode;
  });
  const cellGroup = D.cells.map(function (c) { return c.group; });
  const muted = {};
  const duration = D.duration_s;
  const S = { t: 0, clock: "audio", wallStart: 0, wallPlaying: false, shown: null, drawnT: -1 };

  function frameIndex(t) { return Math.floor(t / binS); }
  function render(t, force) {
    const i = frameIndex(t);
    const f = i >= 0 && i < frames.length ? frames[i] : null;
    const key = (f ? i : -1) + "|" + Object.keys(muted).filter(function (g) { return muted[g]; }).join(",");
    glove.dataset.t = t.toFixed(6);
    if (force || key !== S.shown) {
      S.shown = key;
      glove.dataset.frame = f ? i : -1;
      for (let k = 0; k < 10; k++) {
        const off = muted[cellGroup[k]] === true;
        cellEls[k].classList.toggle("muted", off);
        const byte = f && !off ? f[k] : 0;
        for (let j = 0; j < 8; j++) dots[k][j].classList.toggle("up", ((byte >> j) & 1) === 1);
      }
    }
    timeEl.textContent = t.toFixed(2) + " s";
    if (document.activeElement !== seekEl) seekEl.value = t;
    if (t !== S.drawnT) { draw(t); S.drawnT = t; }
  }

  // ---- lanes: pitch contours and onset rasters, scrolling under a fixed playhead ----
  // The row labels sit in a gutter at the left; the lanes scroll right of it, never over it.
  // The canvas fills its column, and when the column stands beside the glove and its legend
  // its rows grow to their height, so that neither column leaves an empty half.
  const canvas = document.getElementById("lanes");
  const ctx = canvas.getContext("2d");
  const BEFORE = 2, SPAN = 8, GUTTER = 76, TOP = 16;
  const pitchKeys = Object.keys(D.pitch_hz).filter(function (k) { return D.pitch_hz[k].length > 0; });
  const onsetKeys = Object.keys(D.onsets_s);
  const ranges = {};
  pitchKeys.forEach(function (k) {
    let lo = Infinity, hi = -Infinity;
    D.pitch_hz[k].forEach(function (f) { if (f > 0) { const m = 69 + 12 * Math.log2(f / 440); if (m < lo) lo = m; if (m > hi) hi = m; } });
    if (!(hi > lo)) { lo = 40; hi = 80; }
    ranges[k] = [lo - 1, hi + 1];
  });
  const COLOURS = { bass: "#e4572e", kick: "#3b6fd8", snare: "#17a589", toms: "#9b59b6", cymbals: "#d4ac0d", vocals: "#e84393", other: "#2e86c1", drums: "#16a085" };
  const NOTES = ["C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B"];
  function noteName(m) { const n = Math.round(m); return NOTES[((n % 12) + 12) % 12] + (Math.floor(n / 12) - 1); }
  const L = { w: 760, h: 300, laneH: 64, rowH: 16 };
  function layout() {
    const side = document.getElementById("side"), left = document.getElementById("left");
    const w = Math.max(240, canvas.clientWidth || 760);
    const base = TOP + pitchKeys.length * 64 + onsetKeys.length * 16 + 8;
    // The height beside the glove and its legend, less what sits under the lanes.
    const besides = left.offsetTop === side.offsetTop;
    const room = besides ? left.offsetHeight - (side.offsetHeight - canvas.offsetHeight) : 0;
    let laneH = 64, rowH = 16;
    if (room > base && pitchKeys.length > 0) laneH = Math.min(160, 64 + Math.floor((room - base) / pitchKeys.length));
    else if (room > base && onsetKeys.length > 0) rowH = Math.min(32, 16 + Math.floor((room - base) / onsetKeys.length));
    const h = TOP + pitchKeys.length * laneH + onsetKeys.length * rowH + 8;
    const dpr = window.devicePixelRatio || 1;
    L.w = w; L.h = h; L.laneH = laneH; L.rowH = rowH;
    canvas.style.height = h + "px";
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    S.drawnT = -1;
  }
  layout();
  function lowerBound(a, x) { let lo = 0, hi = a.length; while (lo < hi) { const m = (lo + hi) >> 1; if (a[m] < x) lo = m + 1; else hi = m; } return lo; }
  function draw(t) {
    const W = L.w, H = L.h, t0 = t - BEFORE, px = (W - GUTTER) / SPAN;
    function xOf(s) { return GUTTER + (s - t0) * px; }
    ctx.clearRect(0, 0, W, H);
    ctx.font = "11px sans-serif";
    ctx.textAlign = "left";
    ctx.save();
    ctx.beginPath();
    ctx.rect(GUTTER, 0, W - GUTTER, H);
    ctx.clip();
    ctx.fillStyle = "#888";
    for (let s = Math.ceil(t0); s <= t0 + SPAN; s++) {
      const x = xOf(s);
      ctx.fillRect(x, 0, 1, H);
      if (s >= 0) ctx.fillText(s + " s", x + 2, 11);
    }
    let y = TOP;
    pitchKeys.forEach(function (k) {
      const a = D.pitch_hz[k], r = ranges[k], hop = D.hop_s, laneH = L.laneH;
      ctx.strokeStyle = COLOURS[k] || "#444"; ctx.lineWidth = 2; ctx.beginPath();
      const i0 = Math.max(0, Math.floor(t0 / hop)), i1 = Math.min(a.length, Math.ceil((t0 + SPAN) / hop) + 1);
      let pen = false;
      for (let i = i0; i < i1; i++) {
        if (a[i] > 0) {
          const m = 69 + 12 * Math.log2(a[i] / 440);
          const x = xOf(i * hop), yy = y + laneH - 4 - (m - r[0]) / (r[1] - r[0]) * (laneH - 8);
          if (pen) ctx.lineTo(x, yy); else ctx.moveTo(x, yy);
          pen = true;
        } else pen = false;
      }
      ctx.stroke();
      ctx.fillStyle = "#ddd"; ctx.fillRect(GUTTER, y + laneH - 1, W - GUTTER, 1);
      y += laneH;
    });
    onsetKeys.forEach(function (k) {
      const a = D.onsets_s[k], rowH = L.rowH;
      ctx.fillStyle = muted[k] ? "#ccc" : (COLOURS[k] || "#444");
      for (let i = lowerBound(a, t0); i < a.length && a[i] <= t0 + SPAN; i++) ctx.fillRect(xOf(a[i]) - 1, y + 2, 3, rowH - 4);
      y += rowH;
    });
    ctx.fillStyle = "#d00"; ctx.fillRect(GUTTER + BEFORE * px, 0, 2, H);
    ctx.restore();
    // The gutter: each row's name, and each pitch lane's top and bottom as note names.
    ctx.fillStyle = "#ddd"; ctx.fillRect(GUTTER - 1, 0, 1, H);
    y = TOP;
    pitchKeys.forEach(function (k) {
      const r = ranges[k], laneH = L.laneH;
      ctx.fillStyle = "#555"; ctx.fillText(k, 4, y + 12);
      ctx.fillStyle = "#888"; ctx.fillText("pitch", 4, y + 25);
      ctx.textAlign = "right";
      ctx.fillText(noteName(r[1]), GUTTER - 6, y + 12);
      ctx.fillText(noteName(r[0]), GUTTER - 6, y + laneH - 4);
      ctx.textAlign = "left";
      y += laneH;
    });
    onsetKeys.forEach(function (k) {
      ctx.fillStyle = "#555"; ctx.fillText(k, 4, y + L.rowH / 2 + 4);
      y += L.rowH;
    });
  }
  window.addEventListener("resize", function () { layout(); render(S.t, false); });

  // ---- clock ----
  function playing() { return S.clock === "audio" ? !audio.paused : S.wallPlaying; }
  function now() {
    if (S.clock === "audio") return audio.paused ? S.t : audio.currentTime;
    return S.wallPlaying ? (performance.now() - S.wallStart) / 1000 : S.t;
  }
  function clamp(t) { return Math.min(Math.max(t, 0), duration); }
  function seek(t) {
    t = clamp(t);
    S.t = t;
    if (S.clock === "wall") S.wallStart = performance.now() - t * 1000;
    try { audio.currentTime = t; } catch (e) { /* not loaded yet: seeked again on load */ }
    render(t, false);
  }
  function play() {
    if (S.clock === "audio") {
      const p = audio.play();
      if (p && p.catch) p.catch(function (e) { note.textContent = "press space to play (" + e.name + ")"; });
    } else { S.wallStart = performance.now() - S.t * 1000; S.wallPlaying = true; }
    btn.textContent = "❚❚ pause";
  }
  function pause() {
    S.t = now();
    if (S.clock === "audio") audio.pause(); else S.wallPlaying = false;
    btn.textContent = "▶ play";
    render(S.t, false);
  }
  function toggle() { if (playing()) pause(); else play(); }
  function useWallClock(why) {
    const was = playing();
    S.clock = "wall"; S.wallPlaying = false;
    status.dataset.audio = "error"; status.dataset.clock = "wall";
    note.textContent = "audio unavailable (" + why + "): the glove runs on the wall clock, silently";
    if (was) play();
  }
  // Animation-frame statistics while playing, for measurements (window.tactusStats):
  // callbacks, gaps over 25 ms between callbacks (a dropped 60 Hz frame), the longest gap
  // the longest and the total time spent inside callbacks.
  const stats = { frames: 0, late: 0, maxGapMs: 0, maxWorkMs: 0, sumWorkMs: 0 };
  window.tactusStats = stats;
  let lastRaf = -1;
  function loop(ts) {
    const w0 = performance.now();
    if (playing() && lastRaf >= 0) {
      const gap = ts - lastRaf;
      stats.frames++;
      if (gap > 25) stats.late++;
      if (gap > stats.maxGapMs) stats.maxGapMs = gap;
    }
    lastRaf = playing() ? ts : -1;
    if (playing()) {
      const t = now();
      if (t >= duration && S.clock === "wall") { S.wallPlaying = false; S.t = duration; }
      S.t = clamp(t);
    }
    render(S.t, false);
    const work = performance.now() - w0;
    if (playing()) { stats.sumWorkMs += work; if (work > stats.maxWorkMs) stats.maxWorkMs = work; }
    requestAnimationFrame(loop);
  }

  // ---- audio: the source file's bytes, base64 -> blob: URL ----
  const src = document.getElementById("tactus-audio");
  try {
    const b64 = src.textContent.trim();
    const bin = atob(b64);
    const u8 = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) u8[i] = bin.charCodeAt(i);
    audio.src = URL.createObjectURL(new Blob([u8], { type: src.dataset.mime }));
  } catch (e) { useWallClock(e.name); }
  audio.addEventListener("loadedmetadata", function () {
    if (S.clock !== "audio") return;
    status.dataset.audio = "ready";
    if (audio.paused) { try { audio.currentTime = S.t; } catch (e) { } }
  });
  audio.addEventListener("error", function () { if (S.clock === "audio") useWallClock("the browser cannot decode it"); });
  audio.addEventListener("seeked", function () {
    if (audio.paused && S.clock === "audio" && Math.abs(audio.currentTime - S.t) > 0.05) { S.t = audio.currentTime; }
  });
  audio.addEventListener("pause", function () { btn.textContent = "▶ play"; });
  audio.addEventListener("play", function () { btn.textContent = "❚❚ pause"; });
  audio.addEventListener("ended", function () { S.t = duration; });

  // ---- controls ----
  btn.addEventListener("click", toggle);
  seekEl.addEventListener("input", function () { seek(Number(seekEl.value)); });
  document.querySelectorAll("input[data-mute]").forEach(function (cb) {
    cb.addEventListener("change", function () { muted[cb.dataset.mute] = !cb.checked; render(now(), true); draw(now()); });
  });
  document.addEventListener("keydown", function (e) {
    if (e.target && e.target.tagName === "INPUT" && e.target.type !== "checkbox" && e.key !== " ") return;
    if (e.key === " " || e.code === "Space") { e.preventDefault(); toggle(); }
    else if (e.key === "ArrowLeft") { e.preventDefault(); seek(now() - 5); }
    else if (e.key === "ArrowRight") { e.preventDefault(); seek(now() + 5); }
  });
  function fromHash() {
    const h = location.hash.replace(/^#/, "");
    const p = {};
    h.split("&").forEach(function (kv) { if (!kv) return; const i = kv.indexOf("="); p[decodeURIComponent(i < 0 ? kv : kv.slice(0, i))] = i < 0 ? "" : decodeURIComponent(kv.slice(i + 1)); });
    if ("mute" in p) {
      const m = p.mute.split(",");
      document.querySelectorAll("input[data-mute]").forEach(function (cb) {
        const off = m.indexOf(cb.dataset.mute) >= 0;
        cb.checked = !off; muted[cb.dataset.mute] = off;
      });
    }
    if ("t" in p && isFinite(Number(p.t))) {
      if (playing()) pause();
      seek(Number(p.t));
    }
    if ("play" in p) play();
    render(S.t, true);
  }
  window.addEventListener("hashchange", fromHash);
  fromHash();
  requestAnimationFrame(loop);
})();
