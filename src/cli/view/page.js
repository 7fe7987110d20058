// npf view: the page's script. Everything it shows comes from the JSON
// block npf wrote (#npf-data); the sphere is the model's exported GLSL
// evaluator in the scene of npf's CPU renderer (src/render.rs).
"use strict";
const DATA = JSON.parse(document.getElementById("npf-data").textContent);
const logEl = document.getElementById("log");
let failed = false;
function fail(msg) {
  failed = true;
  logEl.textContent += "ERROR " + msg + "\n";
  document.body.dataset.status = "error";
}
window.addEventListener("error", (e) => fail(e.message + " (" + (e.lineno || "?") + ")"));
const $ = (id) => document.getElementById(id);
const SVG = "http://www.w3.org/2000/svg";
function el(tag, attrs, parent, text) {
  const e = tag.startsWith("svg:") ? document.createElementNS(SVG, tag.slice(4)) : document.createElement(tag);
  for (const k in attrs || {}) e.setAttribute(k, attrs[k]);
  if (text !== undefined) e.textContent = text;
  if (parent) parent.appendChild(e);
  return e;
}

// ---- The sphere: WebGL 2 with the exported evaluator -------------------
// The radiance is summed one direction at a time (the lights, then the
// environment's strata, in the order of src/render.rs), one full-screen
// pass each into a float buffer, then shown through npf's display curve.
// One evaluator call per pass, no loop around it: software WebGL
// (SwiftShader) takes minutes to compile a loop around the evaluator, and
// a pass list also lets the page refine progressively.

// The exported evaluator with its constant tables moved into a float
// texture (SwiftShader also compiles large constant arrays slowly); the
// functions are the export's own.
const TAB_WIDTH = 1024;
function splitTables(glsl) {
  const re = /const float (\w+)\[(\d+)\] = float\[\d+\]\(([^)]*)\);/g;
  const offsets = {};
  const values = [];
  const code = glsl.replace(re, (_, name, n, list) => {
    const v = list.split(",").map((x) => parseFloat(x));
    if (v.length !== parseInt(n, 10) || v.some((x) => !isFinite(x))) throw new Error("table " + name + " does not parse");
    offsets[name] = values.length;
    for (const x of v) values.push(x);
    return "";
  });
  // NAME[expr] -> npfview_tab(offset + (expr)), brackets matched.
  const names = Object.keys(offsets);
  if (!names.length) return { code, values: new Float32Array(1) };
  const at = new RegExp("\\b(" + names.join("|") + ")\\[", "g");
  let out = "", i = 0;
  for (let m; (m = at.exec(code)); ) {
    let depth = 1, j = m.index + m[0].length;
    for (; j < code.length && depth; j++) depth += code[j] === "[" ? 1 : code[j] === "]" ? -1 : 0;
    out += code.slice(i, m.index) + "npfview_tab(" + offsets[m[1]] + " + (" + code.slice(m.index + m[0].length, j - 1) + "))";
    i = j;
    at.lastIndex = j;
  }
  return { code: out + code.slice(i), values: new Float32Array(values) };
}

const VERTEX = `#version 300 es
in vec2 p;
void main() { gl_Position = vec4(p, 0.0, 1.0); }`;

// The pixel's shading frame, as src/render.rs's Frame::at (gl_FragCoord
// has its origin at the bottom left, so y needs no flip).
const FRAME = `
bool npfview_frame(float res, out vec3 n, out vec3 t, out vec3 b) {
  float x = 2.0 * gl_FragCoord.x / res - 1.0;
  float y = 2.0 * gl_FragCoord.y / res - 1.0;
  float r2 = x * x + y * y;
  if (r2 >= 1.0) return false;
  n = vec3(x, y, sqrt(1.0 - r2));
  vec3 c = cross(vec3(0.0, 1.0, 0.0), n);
  t = dot(c, c) < 1e-12 ? vec3(1.0, 0.0, 0.0) : normalize(c);
  b = cross(n, t);
  return true;
}`;

function accumulateSource(code) {
  return `#version 300 es
precision highp float;
precision highp int;
out vec4 outColor;
uniform float uRes;
uniform vec3 uDir;
uniform vec3 uE;
uniform highp sampler2D uPrev;
uniform highp sampler2D uTables;
float npfview_tab(int i) { return texelFetch(uTables, ivec2(i % ${TAB_WIDTH}, i / ${TAB_WIDTH}), 0).r; }
${code}
${FRAME}
void main() {
  vec4 prev = texelFetch(uPrev, ivec2(gl_FragCoord.xy), 0);
  vec3 n, t, b;
  if (!npfview_frame(uRes, n, t, b)) { outColor = vec4(0.0); return; }
  vec3 wo = vec3(t.z, b.z, n.z);
  vec3 wi = vec3(dot(uDir, t), dot(uDir, b), dot(uDir, n));
  vec3 add = vec3(0.0);
  if (wi.z > 0.0 && wo.z > 0.0) add = npf_eval(wo, wi) * uE * wi.z;
  outColor = vec4(prev.rgb + add, 1.0);
}`;
}

const DISPLAY = `#version 300 es
precision highp float;
out vec4 outColor;
uniform highp sampler2D uAcc;
uniform float uExposure;
float srgb(float v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055; }
void main() {
  vec4 a = texelFetch(uAcc, ivec2(gl_FragCoord.xy), 0);
  vec3 l = max(a.rgb * uExposure, vec3(0.0));
  vec3 d = l / (1.0 + l);
  outColor = a.a > 0.0 ? vec4(srgb(d.r), srgb(d.g), srgb(d.b), 1.0) : vec4(0.0, 0.0, 0.0, 1.0);
}`;

// The environment of src/render.rs (radiance in world direction w).
function envRadiance(w) {
  const a = 0.55 + 0.45 * w[1], b = (0.5 - 0.5 * w[1]) ** 2;
  return [0.4 * a + 0.3 * b, 0.5 * a + 0.22 * b, 0.7 * a + 0.15 * b];
}

// The directions a scene sums: [direction, irradiance] for each light, then
// each environment stratum with L(w) dOmega (src/render.rs's quadrature).
function sceneDirections(scene, nTheta) {
  const out = scene.lights.map((l) => [l.dir, l.e]);
  if (scene.environment === 0) return out;
  const nPhi = 2 * nTheta, dOmega = 4 * Math.PI / (nTheta * nPhi);
  for (let a = 0; a < nTheta; a++) {
    const y = 1 - 2 * (a + 0.5) / nTheta, r = Math.sqrt(Math.max(0, 1 - y * y));
    for (let q = 0; q < nPhi; q++) {
      const phi = 2 * Math.PI * (q + 0.5) / nPhi;
      const w = [r * Math.cos(phi), y, r * Math.sin(phi)];
      out.push([w, envRadiance(w).map((v) => v * scene.environment * dOmega)]);
    }
  }
  return out;
}

class SphereView {
  constructor(canvas, glsl) {
    this.canvas = canvas;
    const gl = canvas.getContext("webgl2", { preserveDrawingBuffer: true, antialias: false });
    if (!gl) throw new Error("this browser has no WebGL 2");
    if (!gl.getExtension("EXT_color_buffer_float")) throw new Error("WebGL 2 without EXT_color_buffer_float");
    this.gl = gl;
    const tables = splitTables(glsl);
    this.acc = this.program(accumulateSource(tables.code), ["uRes", "uDir", "uE", "uPrev", "uTables"]);
    this.show = this.program(DISPLAY, ["uAcc", "uExposure"]);
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
    // The tables, TAB_WIDTH floats a row, in texture unit 2.
    const rows = Math.max(1, Math.ceil(tables.values.length / TAB_WIDTH));
    const texels = new Float32Array(rows * TAB_WIDTH);
    texels.set(tables.values);
    gl.activeTexture(gl.TEXTURE2);
    gl.bindTexture(gl.TEXTURE_2D, this.texture(TAB_WIDTH, rows, texels));
    this.res = 0;
    this.probe = new Float32Array(4);
  }
  program(fragment, uniforms) {
    const gl = this.gl;
    const compile = (type, src) => {
      const s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(s));
      return s;
    };
    const prog = gl.createProgram();
    gl.attachShader(prog, compile(gl.VERTEX_SHADER, VERTEX));
    gl.attachShader(prog, compile(gl.FRAGMENT_SHADER, fragment));
    gl.bindAttribLocation(prog, 0, "p");
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error("link: " + gl.getProgramInfoLog(prog));
    const u = {};
    for (const name of uniforms) u[name] = gl.getUniformLocation(prog, name);
    return { prog, u };
  }
  texture(w, h, data) {
    const gl = this.gl, tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage2D(gl.TEXTURE_2D, 0, data ? gl.R32F : gl.RGBA32F, w, h, 0, data ? gl.RED : gl.RGBA, gl.FLOAT, data);
    return tex;
  }
  // Two float buffers of the canvas's size, read and written in turn.
  buffers() {
    const gl = this.gl, res = this.canvas.width;
    if (this.res === res) return;
    this.res = res;
    this.ping = [0, 1].map(() => {
      gl.activeTexture(gl.TEXTURE0);
      const tex = this.texture(res, res, null);
      const fb = gl.createFramebuffer();
      gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
      if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) throw new Error("float framebuffer incomplete");
      return { tex, fb };
    });
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  }
  // Start a render: the passes to run are `dirs` ([direction, E] pairs).
  begin(dirs) {
    const gl = this.gl;
    this.buffers();
    this.dirs = dirs;
    this.done = 0;
    this.cur = 0;
    for (const b of this.ping) {
      gl.bindFramebuffer(gl.FRAMEBUFFER, b.fb);
      gl.clearColor(0, 0, 0, 0);
      gl.clear(gl.COLOR_BUFFER_BIT);
    }
    // Off the sphere the buffer stays 0 (alpha 0): one pass marks the disc.
    if (!dirs.length) this.dirs = [[[0, 0, 1], [0, 0, 0]]];
  }
  // Run up to `count` passes; true when every pass has run.
  step(count) {
    const gl = this.gl, { prog, u } = this.acc, res = this.res;
    gl.useProgram(prog);
    gl.viewport(0, 0, res, res);
    gl.uniform1f(u.uRes, res);
    gl.uniform1i(u.uPrev, 0);
    gl.uniform1i(u.uTables, 2);
    const end = Math.min(this.dirs.length, this.done + count);
    for (; this.done < end; this.done++) {
      const [d, e] = this.dirs[this.done];
      const src = this.ping[this.cur], dst = this.ping[1 - this.cur];
      gl.bindFramebuffer(gl.FRAMEBUFFER, dst.fb);
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, src.tex);
      gl.uniform3fv(u.uDir, d);
      gl.uniform3fv(u.uE, e);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      this.cur = 1 - this.cur;
      // Wait for the GPU now and then: Chromium's software WebGL stalls
      // (for minutes) on a long queue of passes issued in one task.
      if (this.done % 4 === 3) gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.FLOAT, this.probe);
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    return this.done >= this.dirs.length;
  }
  // Show the sum so far on the canvas.
  display(exposure) {
    const gl = this.gl, { prog, u } = this.show;
    gl.useProgram(prog);
    gl.viewport(0, 0, this.res, this.res);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, this.ping[this.cur].tex);
    gl.uniform1i(u.uAcc, 0);
    gl.uniform1f(u.uExposure, exposure);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    const err = gl.getError();
    if (err !== gl.NO_ERROR) throw new Error("WebGL error " + err);
  }
}

// The test hook: page.html#shot&res=128&nt=8&scene=0 shows only the
// sphere, at the top left, at that resolution, exposure 1, every pass run
// before the page's load ends. Without `shot`, nt and scene set the
// page's first render, and `sync` runs it whole before the load ends.
function hashParams() {
  const out = {};
  for (const part of location.hash.replace(/^#/, "").split("&")) {
    if (!part) continue;
    const [k, v] = part.split("=");
    out[k] = v === undefined ? true : decodeURIComponent(v);
  }
  return out;
}

function cpuImage(slot, why) {
  el("img", { class: "sphere", src: DATA.cpu.image, width: 256, height: 256, alt: "npf's CPU render" }, slot);
  $("sphere-caption").textContent = "npf's CPU render (" + DATA.cpu.res + " px, " + DATA.cpu.n_theta + " environment strata, the first scene)";
  $("gl-note").textContent = why;
}

function setUpSphere() {
  const slot = $("sphere-slot");
  const params = hashParams();
  if (!DATA.glsl) {
    cpuImage(slot, "No WebGL sphere: " + DATA.glsl_missing);
    return;
  }
  if (params.shot) {
    document.body.classList.add("shot");
    const c = $("shot");
    const res = Math.max(1, Math.min(2048, parseInt(params.res || "128", 10)));
    c.width = c.height = res;
    c.style.width = c.style.height = res + "px";
    c.style.display = "block";
    const view = new SphereView(c, DATA.glsl);
    const scene = DATA.scenes[parseInt(params.scene || "0", 10)];
    view.begin(sceneDirections(scene, parseInt(params.nt || "12", 10)));
    view.step(Infinity);
    view.display(1.0);
    return;
  }
  const canvas = el("canvas", { class: "sphere", width: 256, height: 256 }, slot);
  let view;
  try {
    view = new SphereView(canvas, DATA.glsl);
  } catch (e) {
    slot.removeChild(canvas);
    cpuImage(slot, "WebGL failed (" + e.message + "): npf's CPU render is shown instead.");
    fail(e.message);
    return;
  }
  const sceneSel = $("scene");
  if (params.nt) {
    const sel = $("n-theta");
    if (![...sel.options].some((o) => o.value === params.nt)) el("option", {}, sel, params.nt);
    sel.value = params.nt;
  }
  const key0 = DATA.scenes[0].lights[0].dir.slice();
  let key = key0.slice();
  const scene = () => {
    const base = DATA.scenes[parseInt(sceneSel.value, 10)];
    const lights = base.lights.map((l, k) => (k === 0 ? { dir: key, e: l.e } : l));
    return { lights, environment: base.environment };
  };
  const exposure = () => Math.pow(2, parseFloat($("exposure").value));
  // A render runs its passes over animation frames (about 30 ms of work a
  // frame), showing the sum so far; a change restarts it.
  let frame = 0, started = 0;
  const restart = () => {
    const stops = parseFloat($("exposure").value);
    $("exposure-value").textContent = (stops > 0 ? "+" : "") + stops + " stops";
    $("light-value").textContent = "key light towards (" + key.map((v) => v.toFixed(2)).join(", ") + ")";
    view.begin(sceneDirections(scene(), parseInt($("n-theta").value, 10)));
    started = performance.now();
    if (!frame) frame = requestAnimationFrame(tick);
  };
  let batch = 4;
  const tick = () => {
    frame = 0;
    try {
      const t0 = performance.now();
      const finished = view.step(batch);
      view.display(exposure());
      if (!document.body.dataset.firstFrameMs) {
        // When the first picture was on the canvas (benches/view_pages.sh).
        view.gl.readPixels(0, 0, 1, 1, view.gl.RGBA, view.gl.UNSIGNED_BYTE, new Uint8Array(4));
        document.body.dataset.firstFrameMs = performance.now().toFixed(0);
      }
      const dt = performance.now() - t0;
      batch = Math.max(1, Math.min(256, Math.round(batch * (dt > 40 ? 0.5 : dt < 15 ? 2 : 1))));
      $("sphere-caption").textContent = finished
        ? "WebGL render of the exported GLSL evaluator (" + view.dirs.length + (view.dirs.length === 1 ? " direction, " : " directions, ") + Math.round(performance.now() - started) + " ms); drag to move the key light"
        : "rendering: " + view.done + " of " + view.dirs.length + " directions";
      if (!finished) frame = requestAnimationFrame(tick);
    } catch (e) {
      fail(e.message);
    }
  };
  // The key light comes from the direction of the sphere's normal under the
  // pointer (outside the disc: on the view's horizon).
  let dragging = false;
  const toLight = (ev) => {
    const r = canvas.getBoundingClientRect();
    let x = 2 * (ev.clientX - r.left) / r.width - 1;
    let y = 1 - 2 * (ev.clientY - r.top) / r.height;
    const r2 = x * x + y * y;
    if (r2 > 1) { const s = 1 / Math.sqrt(r2); x *= s; y *= s; }
    key = [x, y, Math.sqrt(Math.max(0, 1 - x * x - y * y))];
  };
  canvas.addEventListener("pointerdown", (ev) => { dragging = true; canvas.setPointerCapture(ev.pointerId); toLight(ev); restart(); });
  canvas.addEventListener("pointermove", (ev) => { if (dragging) { toLight(ev); restart(); } });
  canvas.addEventListener("pointerup", () => { dragging = false; });
  for (const id of ["scene", "n-theta"]) $(id).addEventListener("input", restart);
  $("exposure").addEventListener("input", () => {
    const stops = parseFloat($("exposure").value);
    $("exposure-value").textContent = (stops > 0 ? "+" : "") + stops + " stops";
    view.display(exposure());
  });
  $("reset-light").addEventListener("click", () => { key = key0.slice(); restart(); });
  restart();
  // #sync: the first render runs whole before the load ends (screenshots).
  if (params.sync) {
    while (!view.step(64));
    tick();
  }
}

// ---- Tables --------------------------------------------------------------
function fillTable(table, rows) {
  for (const [k, v] of rows) {
    const tr = el("tr", {}, table);
    el("th", {}, tr, k);
    el("td", {}, tr, v);
  }
}

function fmt(v) {
  if (typeof v !== "number") return String(v);
  if (v === 0 || (Math.abs(v) >= 0.01 && Math.abs(v) < 1e5)) return String(+v.toPrecision(5));
  return v.toExponential(4);
}

function setUpTables() {
  fillTable($("summary"), DATA.summary);
  if (!DATA.fit) {
    $("fit-section").style.display = "none";
  } else {
    const rows = [];
    for (const [k, v] of Object.entries(DATA.fit)) {
      if (v === null || typeof v === "object") continue;
      rows.push([k.replace(/_/g, " "), fmt(v)]);
    }
    const m = DATA.fit.metrics;
    if (m) for (const [k, v] of Object.entries(m)) rows.push(["fit " + k.replace(/_/g, " "), fmt(v)]);
    const auto = DATA.fit.selection && DATA.fit.selection.auto;
    if (auto && auto.candidates) {
      rows.push(["auto's choice", String(auto.candidates[auto.chosen] ? auto.candidates[auto.chosen].name : auto.chosen)]);
      for (const c of auto.candidates)
        rows.push(["auto: " + c.name, "render " + fmt(c.render.mean_db) + " dB, log RMSE " + fmt(c.log_rmse)]);
    }
    fillTable($("fit"), rows);
  }
}

// The reference and the fit in the scene the sphere's menu shows (npf's
// CPU renders, embedded for every scene).
function setUpReference() {
  const r = DATA.reference;
  if (!r) { $("reference-section").style.display = "none"; return; }
  const box = $("reference");
  const imgs = [];
  const fig = (caption) => {
    const f = el("figure", {}, box);
    imgs.push(el("img", { class: "sphere", width: 256, height: 256, alt: caption }, f));
    el("figcaption", {}, f, caption);
  };
  fig("reference: " + r.name);
  fig("the fit (npf's CPU render)");
  fig("|difference| x " + r.difference_gain);
  const e = r.evaluation, m = e.metrics;
  const t = el("table", {}, box);
  const psnrRow = el("tr", {}, t);
  el("th", {}, psnrRow, "rendering PSNR, this scene");
  const psnrCell = el("td", {}, psnrRow);
  fillTable(t, [
    ["rendering PSNR, first scene", fmt(e.render_psnr_db) + " dB (npf compare's)"],
    ["numerical PSNR", fmt(e.numeric_psnr_db) + " dB"],
    ["cosine-weighted RMSE", fmt(m.cos_rmse) + " 1/sr (relative " + fmt(m.rel_cos_rmse) + ")"],
    ["log(1 + f cos) RMSE", fmt(m.log_rmse)],
    ["largest albedo error", (100 * e.max_albedo_error).toFixed(2) + " %"],
    ["samples", m.samples + " (theta <= " + m.max_theta_deg + " deg)"],
    ["renders", DATA.cpu.res + " px, " + DATA.cpu.n_theta + " environment strata"],
  ]);
  const show = () => {
    const k = parseInt($("scene").value || "0", 10);
    const s = r.scenes[k] || r.scenes[0];
    imgs[0].src = s.image;
    imgs[1].src = s.fit_image;
    imgs[2].src = s.difference;
    psnrCell.textContent = fmt(s.psnr_db) + " dB (" + DATA.scenes[k].name + ")";
  };
  $("scene").addEventListener("input", show);
  referenceShow = show;
}
let referenceShow = () => {};

// ---- Plots ---------------------------------------------------------------
const CHANNEL = ["#d62728", "#2ca02c", "#1f77b4"];
const LOBE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2"];

function polarPlot(parent, title, thetaI, thetaO, fit, ref) {
  const W = 220, H = 130, cx = W / 2, cy = H - 14, R = H - 24;
  const svg = el("svg:svg", { width: W, height: H + 4, viewBox: "0 0 " + W + " " + (H + 4) }, null);
  let top = 0;
  for (const set of [fit, ref]) if (set) for (const v of set) for (const c of v) top = Math.max(top, c);
  const f = el("figure", {}, parent);
  f.appendChild(svg);
  el("figcaption", {}, f, title);
  if (!(top > 0)) { el("svg:text", { x: 10, y: 20 }, svg, "zero everywhere"); return; }
  const decades = 4, lo = top / Math.pow(10, decades);
  const rad = (v) => (v > lo ? R * Math.log10(v / lo) / decades : 0);
  for (let k = 1; k <= decades; k++)
    el("svg:path", { class: "grid", d: `M ${cx - R * k / decades} ${cy} A ${R * k / decades} ${R * k / decades} 0 0 1 ${cx + R * k / decades} ${cy}` }, svg);
  el("svg:line", { class: "axis", x1: cx - R, y1: cy, x2: cx + R, y2: cy }, svg);
  // +theta_o on the light's side (right).
  const pt = (k, v) => {
    const th = thetaO[k] * Math.PI / 180, r = rad(v);
    return [cx + r * Math.sin(th), cy - r * Math.cos(th)];
  };
  for (let c = 0; c < 3; c++) {
    const d = fit.map((v, k) => (k ? "L" : "M") + pt(k, v[c]).map((x) => x.toFixed(1)).join(" ")).join(" ");
    el("svg:path", { d, stroke: CHANNEL[c], fill: "none", "stroke-width": 1.3 }, svg);
    if (ref)
      ref.forEach((v, k) => {
        if (k % 4 !== 0 || !(v[c] > lo)) return;
        const [x, y] = pt(k, v[c]);
        el("svg:circle", { cx: x.toFixed(1), cy: y.toFixed(1), r: 1.6, fill: CHANNEL[c], opacity: 0.6 }, svg);
      });
  }
  const ti = thetaI * Math.PI / 180;
  el("svg:line", { x1: cx + R * Math.sin(ti), y1: cy - R * Math.cos(ti), x2: cx, y2: cy, stroke: "#000", "stroke-dasharray": "3 2" }, svg);
  el("svg:text", { x: 4, y: 12 }, svg, "max " + fmt(top) + " 1/sr");
}

function setUpPolar() {
  const p = DATA.plane, box = $("polar");
  p.phi.forEach((phi, a) => {
    p.theta_i.forEach((ti, k) => {
      const ref = p.reference ? p.reference[a][k] : null;
      polarPlot(box, "theta_i = " + ti + " deg" + (p.phi.length > 1 ? ", phi = " + phi + " deg" : ""), ti, p.theta_o, p.fit[a][k], ref);
    });
  });
}

// A line chart: series [{x, y, color, dash, label}], optional log y and
// sqrt x axis, node ticks.
function lineChart(parent, o) {
  const W = 300, H = 200, L = 46, B = 28, T = 18, Rm = 8;
  const svg = el("svg:svg", { width: W, height: H, viewBox: `0 0 ${W} ${H}` }, null);
  const f = el("figure", {}, parent);
  f.appendChild(svg);
  el("figcaption", {}, f, o.caption || "");
  let ys = [];
  for (const s of o.series) for (const v of s.y) if (isFinite(v) && (!o.logY || v > 0)) ys.push(v);
  if (!ys.length) { el("svg:text", { x: 10, y: 30 }, svg, "no positive values"); return; }
  let y0 = Math.min(...ys), y1 = Math.max(...ys);
  if (o.logY) { y0 = Math.max(y0, y1 * 1e-6); y0 = Math.log10(y0); y1 = Math.log10(y1); }
  if (!o.logY) y0 = Math.min(0, y0);
  if (y1 - y0 < 1e-12) { y1 += 0.5; y0 -= 0.5; }
  const xf = o.sqrtX ? (x) => Math.sqrt(x / 90) : (x) => x / 90;
  const X = (x) => L + (W - L - Rm) * xf(x);
  const Y = (y) => {
    const v = o.logY ? Math.log10(Math.max(y, 1e-300)) : y;
    return T + (H - T - B) * (1 - (Math.min(Math.max(v, y0), y1) - y0) / (y1 - y0));
  };
  el("svg:rect", { class: "axis", x: L, y: T, width: W - L - Rm, height: H - T - B }, svg);
  for (const n of o.nodes || []) el("svg:line", { class: "grid", x1: X(n), x2: X(n), y1: T, y2: H - B }, svg);
  for (const s of o.series) {
    const d = s.x.map((x, k) => (k ? "L" : "M") + X(x).toFixed(1) + " " + Y(s.y[k]).toFixed(1)).join(" ");
    el("svg:path", { d, stroke: s.color, fill: "none", "stroke-width": 1.4, "stroke-dasharray": s.dash || "" }, svg);
  }
  const tick = (v) => (o.logY ? "1e" + v.toFixed(0) : fmt(v));
  const yt = o.logY ? [Math.ceil(y0), Math.floor(y1)] : [y0, y1];
  for (const v of yt) el("svg:text", { x: 2, y: Y(o.logY ? Math.pow(10, v) : v) + 4 }, svg, tick(v));
  for (const x of o.sqrtX ? [0, 10, 40, 90] : [0, 30, 60, 90]) el("svg:text", { x: X(x) - 6, y: H - B + 13 }, svg, String(x));
  el("svg:text", { x: L + 4, y: H - 2 }, svg, o.xLabel);
  el("svg:text", { x: L + 4, y: 12 }, svg, o.title);
  let lx = W - Rm - 4;
  for (const s of o.series.filter((s) => s.label).reverse()) {
    const t = el("svg:text", { x: lx, y: 12, "text-anchor": "end", fill: s.color }, svg, s.label);
    lx -= 8 + 6 * s.label.length;
    t.style.fill = s.color;
  }
}

function setUpFactors() {
  const F = DATA.factors, box = $("factors");
  const phiDash = ["", "5 3", "2 2", "8 3 2 3"];
  const lobes = (tab) => {
    const out = [];
    tab.lobes.forEach((perPhi, m) =>
      perPhi.forEach((y, a) =>
        out.push({ x: tab.x, y, color: LOBE[m % LOBE.length], dash: phiDash[a % 4], label: a === 0 ? "lobe " + (m + 1) : "" })));
    return out;
  };
  const phiNote = F.phi.length > 1 ? " (dashes: phi = " + F.phi.join(", ") + " deg)" : "";
  lineChart(box, { title: "D(theta_h)", xLabel: "theta_h (deg, sqrt axis)", series: lobes(F.d), logY: true, sqrtX: true, nodes: F.d.nodes, caption: "microfacet distribution per lobe" + phiNote });
  lineChart(box, { title: "G(theta)", xLabel: "theta (deg)", series: lobes(F.g), nodes: F.g.nodes, caption: "masking per lobe" + phiNote });
  lineChart(box, {
    title: "F(theta_d)", xLabel: "theta_d (deg)", nodes: F.f.nodes, caption: "Fresnel factor per channel",
    series: F.f.channels.map((y, c) => ({ x: F.f.x, y, color: CHANNEL[c], label: "RGB"[c] })),
  });
  if (F.p) lineChart(box, { title: "P(theta)", xLabel: "theta (deg)", nodes: F.p.x, caption: "separable diffuse factor", series: [{ x: F.p.x, y: F.p.p, color: "#444" }] });
  const t = el("table", {}, box);
  fillTable(t, [["d (1/sr)", F.diffuse.map(fmt).join(" ")]].concat(F.s.map((s, m) => ["s, lobe " + (m + 1), s.map(fmt).join(" ")])));
}

// The scene menu (the sphere and the reference follow it); #scene=K
// chooses the first.
function setUpScenes() {
  const sel = $("scene");
  DATA.scenes.forEach((s, k) => el("option", { value: k }, sel, s.name));
  const k = hashParams().scene;
  if (k && DATA.scenes[k]) sel.value = k;
}

function main() {
  const steps = [setUpScenes, setUpTables, setUpReference, setUpSphere, setUpPolar, setUpFactors, () => referenceShow()];
  for (const step of steps) {
    try {
      step();
    } catch (e) {
      fail(step.name + ": " + e.message);
    }
  }
  if (!failed) document.body.dataset.status = "ok";
  // When the page was ready (ms after navigation started): benches/view_pages.sh.
  document.body.dataset.readyMs = performance.now().toFixed(0);
}
main();
