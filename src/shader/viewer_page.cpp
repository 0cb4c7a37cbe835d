#include "shader/viewer_page.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "util/error.h"

namespace nbtf {
namespace {

// The page: static HTML, CSS and script; @NBTF_DATA@ becomes the material's JSON.
const char* kPage = R"nbtfpage(<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>nbtf view</title>
<style>
  body { font: 14px/1.4 system-ui, sans-serif; margin: 12px; background: #202124; color: #e8eaed; }
  h1 { font-size: 16px; margin: 0 0 8px 0; }
  #panels { display: flex; gap: 16px; align-items: flex-start; flex-wrap: wrap; }
  #side { flex: 0 0 340px; }
  canvas { background: #404040; display: block; }
  #view { width: 640px; height: 640px; image-rendering: pixelated; }
  #view { cursor: crosshair; }
  .controls { display: grid; grid-template-columns: max-content 130px 3.5em; gap: 4px 10px; align-items: center; }
  .note { color: #9aa0a6; font-size: 12px; }
  #stats { font-family: ui-monospace, monospace; margin: 10px 0; max-width: 330px; white-space: pre-wrap; }
  figure { margin: 0; } figcaption { font-size: 12px; color: #9aa0a6; }
  #nbtf-result { display: none; } body.results #nbtf-result { display: block; }
</style>
</head>
<body>
<h1 id="title">nbtf view</h1>
<div id="panels">
  <figure style="width: 640px"><canvas id="view" width="640" height="640"></canvas>
    <figcaption>Move the mouse: light. Drag: view (orbit). Shift-drag: light without following the mouse. Wheel: distance.</figcaption></figure>
  <div id="side">
    <div class="controls">
      <label for="shape">object</label>
      <select id="shape"><option value="plane">plane</option><option value="sphere" selected>sphere</option><option value="cloth">cloth</option></select><span></span>
      <label for="tiling">tiling</label><input id="tiling" type="range" min="1" max="16" step="1" value="2"><span id="tilingv"></span>
      <label for="exposure">exposure (stops)</label><input id="exposure" type="range" min="-5" max="5" step="0.1" value="0"><span id="exposurev"></span>
      <label for="sun">light strength</label><input id="sun" type="range" min="0" max="4" step="0.05" value="1"><span id="sunv"></span>
      <label for="env">environment</label><input id="env" type="range" min="0" max="1" step="0.05" value="0.25"><span id="envv"></span>
      <label for="scale">resolution</label>
      <select id="scale"><option value="1" selected>640 x 640</option><option value="0.5">320 x 320</option><option value="0.25">160 x 160</option></select><span></span>
      <label for="follow">light follows the mouse</label><input id="follow" type="checkbox" checked><span></span>
    </div>
    <div id="stats">loading</div>
    <figure id="refpanel" style="display:none"><canvas id="reference" width="320" height="320"></canvas>
      <figcaption id="refcaption">measured</figcaption></figure>
  </div>
</div>
<p class="note" id="about"></p>
<pre id="nbtf-result"></pre>
<script id="nbtf-data" type="application/json">@NBTF_DATA@</script>
<script>
'use strict';
const D = JSON.parse(document.getElementById('nbtf-data').textContent);
const result = document.getElementById('nbtf-result');
const stats = document.getElementById('stats');
const hash = location.hash || '';

// The result line is for the test and bench modes (and the browser tests that read it); in
// the interactive page it is written but not shown.
function report(obj) { result.textContent = JSON.stringify(obj); if (obj.mode !== 'view') document.body.classList.add('results'); }
function fail(message) {
  report({status: 'error', message: message});
  stats.textContent = 'error: ' + message;
  throw new Error(message);
}

function bytesOf(b64) {
  const bin = atob(b64);
  const a = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; ++i) a[i] = bin.charCodeAt(i);
  return a;
}

// ---- Small vector and matrix functions (column-major 4 x 4)
const V = {
  sub: (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]],
  dot: (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2],
  cross: (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]],
  norm: (a) => { const l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; },
};
function perspective(fovDeg, aspect, near, far) {
  const f = 1 / Math.tan(fovDeg * Math.PI / 360);
  return [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, 2 * far * near / (near - far), 0];
}
function lookAt(eye, target, up) {
  const z = V.norm(V.sub(eye, target)), x = V.norm(V.cross(up, z)), y = V.cross(z, x);
  return [x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0, -V.dot(x, eye), -V.dot(y, eye), -V.dot(z, eye), 1];
}
function mul(a, b) {
  const o = new Array(16).fill(0);
  for (let c = 0; c < 4; ++c) for (let r = 0; r < 4; ++r) for (let k = 0; k < 4; ++k) o[4 * c + r] += a[4 * k + r] * b[4 * c + k];
  return o;
}
// Degrees theta (from the normal), phi -> unit vector in the local frame (z = the normal).
function unitOf(thetaDeg, phiDeg) {
  const t = thetaDeg * Math.PI / 180, p = phiDeg * Math.PI / 180;
  return [Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t)];
}
// The azimuth, in the material's (the BTF's) frame, of the world direction at azimuth phiDeg:
// the plane's local frame is n = +y, u = +x, v = -z (drawReference's toLocal), so phi turns
// the other way round.
function materialPhi(phiDeg) { return (360 - phiDeg) % 360; }
// World direction of a light at theta from +y, phi from +x towards +z (as nbtf render).
function worldDir(thetaDeg, phiDeg) {
  const t = thetaDeg * Math.PI / 180, p = phiDeg * Math.PI / 180;
  return [Math.sin(t) * Math.cos(p), Math.cos(t), Math.sin(t) * Math.sin(p)];
}

// ---- WebGL2 and the decoder's textures
const canvas = document.getElementById('view');
const gl = canvas.getContext('webgl2', {antialias: false, preserveDrawingBuffer: true});
if (!gl) fail('WebGL2 is not available in this browser');
const units = [];
D.textures.forEach((t, i) => {
  const bytes = bytesOf(t.data);
  if (bytes.length !== t.width * t.height * 16) fail('texture ' + t.uniform + ' holds ' + bytes.length + ' bytes, expected ' + t.width * t.height * 16);
  const tex = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0 + i);
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, t.width, t.height, 0, gl.RGBA, gl.FLOAT, new Float32Array(bytes.buffer));
  units.push([t.uniform, i]);
});

// The weights' uniform blocks (when the decoder keeps its weights there): binding i = block i.
const blocks = (D.blocks || []).map((b, i) => {
  const buffer = gl.createBuffer();
  gl.bindBuffer(gl.UNIFORM_BUFFER, buffer);
  gl.bufferData(gl.UNIFORM_BUFFER, bytesOf(b.data), gl.STATIC_DRAW);
  gl.bindBufferBase(gl.UNIFORM_BUFFER, i, buffer);
  return b.block;
});

function compile(type, source) {
  const s = gl.createShader(type);
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) fail('shader does not compile: ' + gl.getShaderInfoLog(s));
  return s;
}
function program(vertex, fragment) {
  const p = gl.createProgram();
  gl.attachShader(p, compile(gl.VERTEX_SHADER, vertex));
  gl.attachShader(p, compile(gl.FRAGMENT_SHADER, fragment));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) fail('program does not link: ' + gl.getProgramInfoLog(p));
  gl.useProgram(p);
  for (const [name, unit] of units) gl.uniform1i(gl.getUniformLocation(p, name), unit);
  blocks.forEach((name, i) => {
    const index = gl.getUniformBlockIndex(p, name);
    if (index === gl.INVALID_INDEX) fail('uniform block ' + name + ' not found in the program');
    gl.uniformBlockBinding(p, index, i);
  });
  p.u = (name) => gl.getUniformLocation(p, name);
  return p;
}

const sceneVertex = `#version 300 es
layout(location = 0) in vec3 aPos; layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec3 aTangent; layout(location = 3) in vec2 aUv;
uniform mat4 uViewProj;
out vec3 vPos; out vec3 vNormal; out vec3 vTangent; out vec2 vUv;
void main() { vPos = aPos; vNormal = aNormal; vTangent = aTangent; vUv = aUv; gl_Position = uViewProj * vec4(aPos, 1.0); }`;
// Shading as nbtf render (docs/render.md): L = sun BTF(l, v) + env BTF(n, v); the local frame:
// z = the normal turned towards the viewer, x = the tangent along u, y = z x x.
const sceneFragment = D.prelude + D.glsl + `
in vec3 vPos; in vec3 vNormal; in vec3 vTangent; in vec2 vUv;
uniform vec3 uLight; uniform vec3 uEye; uniform float uTiling; uniform float uExposure; uniform float uSun; uniform float uEnv;
out vec4 fragColor;
vec3 srgbEncode(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}
void main() {
  vec3 n = normalize(vNormal), v = normalize(uEye - vPos);
  if (dot(n, v) < 0.0) n = -n;
  vec3 t = vTangent - n * dot(n, vTangent);
  t = dot(t, t) > 1e-12 ? normalize(t) : normalize(cross(n, abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0)));
  vec3 b = cross(n, t);
  vec3 vl = normalize(vec3(dot(v, t), dot(v, b), max(dot(v, n), 0.0)));
  vec3 ll = vec3(dot(uLight, t), dot(uLight, b), dot(uLight, n));
  vec2 uv = vUv * uTiling;
  vec3 c = vec3(0.0);
  if (ll.z > 0.0 && uSun > 0.0) c += uSun * max(nbtf_decode(uv, normalize(ll), vl), vec3(0.0));
  if (uEnv > 0.0) c += uEnv * max(nbtf_decode(uv, vec3(0.0, 0.0, 1.0), vl), vec3(0.0));
  fragColor = vec4(srgbEncode(c * uExposure), 1.0);
}`;
// The texel grid: pixel (x, y) of a width x height target decodes texel (x, y) at one pair.
const gridVertex = `#version 300 es
void main() { vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0); gl_Position = vec4(p, 0.0, 1.0); }`;
const gridFragment = D.prelude + D.glsl + `
uniform vec3 uL; uniform vec3 uV; uniform vec2 uSize;
out vec4 fragColor;
void main() { fragColor = vec4(nbtf_decode(gl_FragCoord.xy / uSize, uL, uV), 1.0); }`;

// ---- Objects: position, normal, tangent (along u), uv
function mesh(build) {
  const m = build();
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const buffer = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(m.v), gl.STATIC_DRAW);
  const names = [['aPos', 3, 0], ['aNormal', 3, 3], ['aTangent', 3, 6], ['aUv', 2, 9]];
  names.forEach(([name, size, offset], i) => {
    gl.enableVertexAttribArray(i);
    gl.vertexAttribPointer(i, size, gl.FLOAT, false, 44, offset * 4);
  });
  const index = gl.createBuffer();
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, index);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, new Uint32Array(m.i), gl.STATIC_DRAW);
  gl.bindVertexArray(null);
  return {vao: vao, count: m.i.length};
}
function grid(nu, nv, vertexAt) {
  const v = [], i = [];
  for (let b = 0; b <= nv; ++b) for (let a = 0; a <= nu; ++a) v.push(...vertexAt(a / nu, b / nv));
  for (let b = 0; b < nv; ++b) for (let a = 0; a < nu; ++a) {
    const p = b * (nu + 1) + a, q = p + nu + 1;
    i.push(p, q, p + 1, p + 1, q, q + 1);
  }
  return {v: v, i: i};
}
const objects = {
  // As nbtf render's plane: u along +x, v along -z (so the local y = n x tangent = -z grows with v).
  plane: () => grid(1, 1, (s, t) => [2 * s - 1, 0, 2 * t - 1, 0, 1, 0, 1, 0, 0, s, 1 - t]),
  sphere: () => grid(128, 64, (s, t) => {
    const phi = 2 * Math.PI * s, theta = Math.PI * t;
    const n = [Math.sin(theta) * Math.cos(phi), Math.cos(theta), Math.sin(theta) * Math.sin(phi)];
    return [...n, ...n, -Math.sin(phi), 0, Math.cos(phi), s, t / 2];
  }),
  // The draped sheet of nbtf render's cloth scene: y = 0.12 + 0.8 g + 0.06 sin(5x + 2z)(1 - g).
  cloth: () => grid(160, 160, (s, t) => {
    const h = (x, z) => { const g = Math.exp(-(x * x + z * z) / 0.45); return 0.12 + 0.8 * g + 0.06 * Math.sin(5 * x + 2 * z) * (1 - g); };
    const x = 2.6 * s - 1.3, z = 2.6 * t - 1.3, e = 1e-4;
    const dx = (h(x + e, z) - h(x - e, z)) / (2 * e), dz = (h(x, z + e) - h(x, z - e)) / (2 * e);
    return [x, h(x, z) - 0.4, z, ...V.norm([-dx, 1, -dz]), ...V.norm([1, dx, 0]), s, t];
  }),
};

// ---- The page's state
const state = {shape: 'sphere', azimuth: 25, elevation: 40, distance: 3.4, lightTheta: 45, lightPhi: 300,
               tiling: 2, exposure: 0, sun: 1, env: 0.25};
function eyeOf(s) {
  const a = s.azimuth * Math.PI / 180, e = s.elevation * Math.PI / 180;
  return [s.distance * Math.cos(e) * Math.sin(a), s.distance * Math.sin(e), s.distance * Math.cos(e) * Math.cos(a)];
}

let sceneProgram = null, meshes = {};
function drawScene(width, height) {
  gl.viewport(0, 0, width, height);
  gl.clearColor(0.25, 0.25, 0.25, 0);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.enable(gl.DEPTH_TEST);
  gl.useProgram(sceneProgram);
  const eye = eyeOf(state);
  gl.uniformMatrix4fv(sceneProgram.u('uViewProj'), false, mul(perspective(40, width / height, 0.05, 50), lookAt(eye, [0, 0, 0], [0, 1, 0])));
  gl.uniform3fv(sceneProgram.u('uLight'), worldDir(state.lightTheta, state.lightPhi));
  gl.uniform3fv(sceneProgram.u('uEye'), eye);
  gl.uniform1f(sceneProgram.u('uTiling'), state.tiling);
  gl.uniform1f(sceneProgram.u('uExposure'), Math.pow(2, state.exposure));
  gl.uniform1f(sceneProgram.u('uSun'), state.sun);
  gl.uniform1f(sceneProgram.u('uEnv'), state.env);
  const m = meshes[state.shape] || (meshes[state.shape] = mesh(objects[state.shape]));
  gl.bindVertexArray(m.vao);
  gl.drawElements(gl.TRIANGLES, m.count, gl.UNSIGNED_INT, 0);
  gl.bindVertexArray(null);
}

// ---- #test: the texel grid at fixed pairs, linear RGB read back as float32
function runTest() {
  if (!gl.getExtension('EXT_color_buffer_float')) fail('EXT_color_buffer_float is not available: cannot read float pixels back');
  const p = program(gridVertex, gridFragment);
  const w = D.width, h = D.height;
  const fb = gl.createFramebuffer(), tex = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0 + units.length);
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, w, h, 0, gl.RGBA, gl.FLOAT, null);
  gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
  if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) fail('float framebuffer incomplete');
  gl.viewport(0, 0, w, h);
  gl.uniform2f(p.u('uSize'), w, h);
  const pairs = [];
  const pixels = new Float32Array(w * h * 4);
  for (const [lt, lp, vt, vp] of D.testPairs) {
    gl.uniform3fv(p.u('uL'), unitOf(lt, lp));
    gl.uniform3fv(p.u('uV'), unitOf(vt, vp));
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.FLOAT, pixels);
    const rgb = [];
    for (let i = 0; i < w * h; ++i) rgb.push(pixels[4 * i], pixels[4 * i + 1], pixels[4 * i + 2]);
    pairs.push({light: [lt, lp], view: [vt, vp], rgb: rgb});
  }
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  report({status: 'ok', mode: 'test', width: w, height: h, pairs: pairs});
  stats.textContent = 'test mode: ' + pairs.length + ' pairs rendered';
}

// ---- #bench=N: the default view of the plane at N x N, a few frames, milliseconds per frame
function runBench(n, count) {
  sceneProgram = program(sceneVertex, sceneFragment);
  const fb = gl.createFramebuffer(), color = gl.createRenderbuffer(), depth = gl.createRenderbuffer();
  gl.bindRenderbuffer(gl.RENDERBUFFER, color);
  gl.renderbufferStorage(gl.RENDERBUFFER, gl.RGBA8, n, n);
  gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
  gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, n, n);
  gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.RENDERBUFFER, color);
  gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
  Object.assign(state, {shape: 'plane', env: 0, tiling: 1});
  const one = new Uint8Array(4);
  drawScene(n, n);  // warm-up: compiles and uploads
  gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, one);
  const frames = [];
  for (let k = 0; k < count; ++k) {
    const t0 = performance.now();
    drawScene(n, n);
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, one);
    frames.push(performance.now() - t0);
  }
  const all = new Uint8Array(n * n * 4);
  gl.readPixels(0, 0, n, n, gl.RGBA, gl.UNSIGNED_BYTE, all);
  let covered = 0;
  for (let i = 3; i < all.length; i += 4) if (all[i] > 0) ++covered;
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  frames.sort((a, b) => a - b);
  const median = frames[Math.floor(frames.length / 2)];
  const eye = eyeOf(state);
  report({status: 'ok', mode: 'bench', size: n, frame_ms: median, frames_ms: frames, material_pixels: covered,
          camera: eye.concat([0, 0, 0, 40]), light: [state.lightTheta, state.lightPhi]});
  stats.textContent = 'bench: ' + median.toFixed(1) + ' ms per ' + n + ' x ' + n + ' frame';
}

// ---- The measured image nearest to the light and view at the plane's centre
let refCanvas = null, refImages = null, lastRef = -1;
function nearestIndex(set, d) {
  let best = 0, bestDot = -2;
  set.forEach(([t, p], i) => { const u = unitOf(t, p), c = V.dot(u, d); if (c > bestDot) { bestDot = c; best = i; } });
  return best;
}
function drawReference() {
  if (!D.reference) return;
  // The plane's local frame: n = +y, tangent x = +x, y = n x x = -z.
  const toLocal = (w) => [w[0], -w[2], w[1]];
  const l = toLocal(worldDir(state.lightTheta, state.lightPhi)), v = toLocal(V.norm(eyeOf(state)));
  const R = D.reference;
  const li = nearestIndex(R.lights, l), vi = nearestIndex(R.views, v), image = li * R.views.length + vi;
  if (image === lastRef) return;
  lastRef = image;
  const size = R.width * R.height, img = new ImageData(R.width, R.height);
  for (let i = 0; i < size; ++i) {
    const o = 3 * (image * size + i);
    img.data[4 * i] = refImages[o]; img.data[4 * i + 1] = refImages[o + 1]; img.data[4 * i + 2] = refImages[o + 2]; img.data[4 * i + 3] = 255;
  }
  const c = refCanvas.getContext('2d');
  const tmp = document.createElement('canvas');
  tmp.width = R.width; tmp.height = R.height;
  tmp.getContext('2d').putImageData(img, 0, 0);
  c.imageSmoothingEnabled = false;
  c.drawImage(tmp, 0, 0, refCanvas.width, refCanvas.height);
  const f = (d) => '(' + d[0] + '\u00b0, ' + d[1] + '\u00b0)';
  const subset = R.lights.length < R.measured_lights || R.views.length < R.measured_views;
  document.getElementById('refcaption').textContent = 'measured, nearest ' + (subset ? 'embedded ' : '') +
      'pair to the plane centre: light ' + f(R.lights[li]) + ', view ' + f(R.views[vi]) + ' (the material\'s frame)' +
      (subset ? '; ' + R.lights.length + ' of ' + R.measured_lights + ' lights x ' + R.views.length + ' of ' +
                R.measured_views + ' views embedded' : '') +
      (R.fingerprint.startsWith('MISMATCH') ? '; NOT the material this file was made from (--force)' : '');
}

// ---- Interactive mode
function interactive() {
  sceneProgram = program(sceneVertex, sceneFragment);
  if (D.reference) {
    refCanvas = document.getElementById('reference');
    refImages = bytesOf(D.reference.data);
    document.getElementById('refpanel').style.display = '';
  }
  let pending = false, lastMs = 0;
  const onePixel = new Uint8Array(4);
  const frame = () => {
    pending = false;
    const t0 = performance.now();
    drawScene(canvas.width, canvas.height);
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, onePixel);  // waits for the frame
    lastMs = performance.now() - t0;
    stats.textContent = 'frame ' + lastMs.toFixed(1) + ' ms (draw until its pixels are read back, ' + canvas.width + ' x ' + canvas.height +
        ')\nlight (' + state.lightTheta.toFixed(0) + '\u00b0, ' + materialPhi(state.lightPhi).toFixed(0) +
        '\u00b0) in the material\'s frame (theta from the normal, phi from the texture\'s u axis)' +
        '\n' + D.cost.operations.toFixed(0) + ' operations, ' + D.cost.uniform_loads.toFixed(0) + ' uniform loads, ' +
        D.cost.texture_fetches.toFixed(0) + ' texture fetches per decode';
    drawReference();
  };
  const redraw = () => { if (!pending) { pending = true; requestAnimationFrame(frame); } };
  const bind = (id, key, show) => {
    const el = document.getElementById(id), out = document.getElementById(id + 'v');
    const initial = new RegExp(id + '=([a-z0-9.+-]+)').exec(hash);  // e.g. #shape=cloth&tiling=4
    if (initial) el.value = initial[1];
    const update = () => { state[key] = id === 'shape' ? el.value : parseFloat(el.value); if (out) out.textContent = show(state[key]); redraw(); };
    el.addEventListener('input', update);
    update();
  };
  bind('shape', 'shape', (x) => x);
  // #scale=S (or the menu): draw S x 640 pixels, for software rasterizers.
  const scaleMenu = document.getElementById('scale');
  const hashScale = /scale=([0-9.]+)/.exec(hash);
  if (hashScale) scaleMenu.value = hashScale[1];
  const applyScale = () => { canvas.width = canvas.height = Math.round(640 * (parseFloat(scaleMenu.value) || 1)); redraw(); };
  scaleMenu.addEventListener('input', applyScale);
  applyScale();
  bind('tiling', 'tiling', (x) => x + ' x');
  bind('exposure', 'exposure', (x) => (x >= 0 ? '+' : '') + x.toFixed(1));
  bind('sun', 'sun', (x) => x.toFixed(2));
  bind('env', 'env', (x) => x.toFixed(2));
  let drag = null;
  const setLight = (e) => {
    const r = canvas.getBoundingClientRect();
    const x = 2 * (e.clientX - r.left) / r.width - 1, y = 1 - 2 * (e.clientY - r.top) / r.height;
    const rr = Math.min(1, Math.hypot(x, y));
    state.lightTheta = 88 * rr;
    // The mouse seen from above: right on the screen is the camera's right, up is away from
    // the camera (azimuth a: the eye towards (sin a, cos a) in x, z).
    const a = state.azimuth * Math.PI / 180;
    const wx = x * Math.cos(a) - y * Math.sin(a), wz = -x * Math.sin(a) - y * Math.cos(a);
    state.lightPhi = (Math.atan2(wz, wx) * 180 / Math.PI + 360) % 360;
    redraw();
  };
  canvas.addEventListener('mousedown', (e) => { drag = {x: e.clientX, y: e.clientY, shift: e.shiftKey}; e.preventDefault(); });
  window.addEventListener('mouseup', () => { drag = null; });
  canvas.addEventListener('mousemove', (e) => {
    if (drag && !drag.shift) {
      state.azimuth -= 0.4 * (e.clientX - drag.x);
      state.elevation = Math.max(2, Math.min(89, state.elevation + 0.4 * (e.clientY - drag.y)));
      drag.x = e.clientX; drag.y = e.clientY;
      redraw();
    } else if ((drag && drag.shift) || document.getElementById('follow').checked) {
      setLight(e);
    }
  });
  canvas.addEventListener('wheel', (e) => { state.distance = Math.max(1.5, Math.min(10, state.distance * Math.exp(0.001 * e.deltaY))); e.preventDefault(); redraw(); }, {passive: false});
  frame();
  report({status: 'ok', mode: 'view', frame_ms: lastMs});
}

try {
  document.getElementById('title').textContent = 'nbtf view: ' + D.title + ' (' + D.method + ', ' + D.width + ' x ' + D.height + ' texels)';
  document.title = 'nbtf view: ' + D.title;
  document.getElementById('about').textContent = 'The decoder runs in this page as a GLSL ES 3.00 fragment shader (nbtf export-shader); ' +
      'nothing is fetched from the network. URL fragment: #shape=cloth&tiling=4&exposure=1&scale=0.5 sets the controls; ' +
      '#test renders the texel grid at fixed pairs, #bench=1024,3 times 3 frames of 1024 x 1024.';
  if (hash === '#test') runTest();
  else if (hash.startsWith('#bench=')) {
    const [n, frames] = hash.substring(7).split(',').map((x) => parseInt(x));
    runBench(n || 1024, frames || 3);
  }
  else interactive();
} catch (e) {
  if (!result.textContent) report({status: 'error', message: String(e && e.message || e)});
  stats.textContent = 'error: ' + (e && e.message || e);
}
</script>
</body>
</html>
)nbtfpage";

const char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

}  // namespace

std::string base64Encode(const void* data, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(data);
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 3 <= size; i += 3) {
    const unsigned v = (p[i] << 16) | (p[i + 1] << 8) | p[i + 2];
    out += kBase64[v >> 18], out += kBase64[(v >> 12) & 63], out += kBase64[(v >> 6) & 63], out += kBase64[v & 63];
  }
  if (i < size) {
    const unsigned v = (p[i] << 16) | (i + 1 < size ? p[i + 1] << 8 : 0);
    out += kBase64[v >> 18], out += kBase64[(v >> 12) & 63];
    out += i + 1 < size ? kBase64[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

namespace {

// `count` of the directions, each the farthest (largest angle) from those already taken,
// starting from the one nearest the normal: an even spread over the hemisphere, in index order.
std::vector<int> spreadDirections(const std::vector<Direction>& dirs, std::size_t count) {
  const std::size_t n = dirs.size();
  if (count >= n) {
    std::vector<int> all(n);
    for (std::size_t i = 0; i < n; ++i) all[i] = static_cast<int>(i);
    return all;
  }
  std::vector<std::array<double, 3>> unit(n);
  for (std::size_t i = 0; i < n; ++i) unit[i] = dirs[i].unitVector();
  std::vector<double> nearest(n, 2.0);  // 1 - cos of the angle to the nearest taken direction
  std::vector<int> taken;
  std::size_t next = 0;
  for (std::size_t i = 1; i < n; ++i)
    if (dirs[i].thetaDeg < dirs[next].thetaDeg) next = i;
  while (taken.size() < count) {
    taken.push_back(static_cast<int>(next));
    for (std::size_t i = 0; i < n; ++i) {
      const auto& a = unit[i];
      const auto& b = unit[next];
      nearest[i] = std::min(nearest[i], 1.0 - (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]));
    }
    for (std::size_t i = 0; i < n; ++i)
      if (nearest[i] > nearest[next]) next = i;
  }
  std::sort(taken.begin(), taken.end());
  return taken;
}

}  // namespace

ViewerReferenceSelection viewerReferenceDirections(const std::vector<Direction>& lights,
                                                   const std::vector<Direction>& views, std::size_t texels) {
  const std::size_t imageBytes = texels * 3, fit = kMaxViewerReferenceBytes / std::max<std::size_t>(imageBytes, 1);
  if (fit < 1)
    throw Error("one image of " + std::to_string(texels) + " texels is " + std::to_string(imageBytes >> 20) +
                " MiB as 8-bit RGB, more than the " + std::to_string(kMaxViewerReferenceBytes >> 20) +
                " MiB a page embeds; crop it (--crop)");
  std::size_t nl = lights.size(), nv = views.size();
  if (nl * nv > fit) {
    const double f = std::sqrt(static_cast<double>(fit) / static_cast<double>(nl * nv));
    nl = std::max<std::size_t>(1, static_cast<std::size_t>(std::floor(f * lights.size())));
    nv = std::max<std::size_t>(1, static_cast<std::size_t>(std::floor(f * views.size())));
    while (nl * nv > fit) (nl >= nv ? nl : nv) -= 1;
  }
  return {spreadDirections(lights, nl), spreadDirections(views, nv)};
}

std::vector<std::pair<Direction, Direction>> viewerTestPairs(const CompressedBtf& m) {
  std::vector<std::pair<Direction, Direction>> pairs;
  if (!m.lights.empty() && !m.views.empty()) {
    pairs.push_back({m.lights.front(), m.views.front()});
    pairs.push_back({m.lights.back(), m.views.back()});
  }
  pairs.push_back({{0, 0}, {0, 0}});
  pairs.push_back({{30, 60}, {45, 180}});
  pairs.push_back({{60, 200}, {20, 30}});
  pairs.push_back({{75, 10}, {70, 190}});
  pairs.push_back({{12.5, 300}, {85, 95}});
  return pairs;
}

std::string buildViewerPage(const ShaderDecoder& shader, const CompressedBtf& material, const ViewerOptions& options) {
  using nlohmann::json;
  json d;
  d["title"] = options.title.empty() ? std::filesystem::path(shader.name).filename().string() : options.title;
  d["method"] = codecMethodName(material.method);
  d["width"] = material.width;
  d["height"] = material.height;
  d["prelude"] = glslPrelude();
  d["glsl"] = shader.glsl;
  json textures = json::array();
  for (const ShaderTexture& t : shader.textures)
    textures.push_back({{"uniform", t.uniform},
                        {"width", t.width},
                        {"height", t.height},
                        {"data", base64Encode(t.data.data(), t.data.size() * sizeof(float))}});
  d["textures"] = textures;
  json pairs = json::array();
  for (const auto& [l, v] : viewerTestPairs(material)) pairs.push_back({l.thetaDeg, l.phiDeg, v.thetaDeg, v.phiDeg});
  d["testPairs"] = pairs;
  d["cost"] = {{"operations", shader.cost.operations()},
               {"multiply_adds", shader.cost.multiplyAdds},
               {"texture_fetches", shader.cost.textureFetches},
               {"uniform_loads", shader.cost.uniformLoads}};
  json blocks = json::array();
  for (const ShaderUniformBlock& b : shader.uniformBlocks)
    blocks.push_back({{"block", b.block}, {"data", base64Encode(b.data.data(), b.data.size() * sizeof(float))}});
  d["blocks"] = blocks;
  d["reference"] = nullptr;
  if (const ViewerReference* r = options.reference) {
    const std::size_t expected = static_cast<std::size_t>(r->width) * r->height * 3 * r->lights.size() * r->views.size();
    if (r->srgb.size() != expected)
      throw Error(r->name + ": reference images hold " + std::to_string(r->srgb.size()) + " bytes, expected " +
                  std::to_string(expected));
    if (expected > kMaxViewerReferenceBytes)
      throw Error(r->name + ": " + std::to_string(r->lights.size() * r->views.size()) + " images of " +
                  std::to_string(r->width) + " x " + std::to_string(r->height) + " are " +
                  std::to_string(expected >> 20) + " MiB as 8-bit RGB, more than the " +
                  std::to_string(kMaxViewerReferenceBytes >> 20) +
                  " MiB a page embeds; pass a smaller stack or crop it (--crop)");
    json lights = json::array(), views = json::array();
    for (const Direction& x : r->lights) lights.push_back({x.thetaDeg, x.phiDeg});
    for (const Direction& x : r->views) views.push_back({x.thetaDeg, x.phiDeg});
    d["reference"] = {{"width", r->width}, {"height", r->height}, {"lights", lights}, {"views", views},
                      {"measured_lights", r->measuredLights ? r->measuredLights : int(r->lights.size())},
                      {"measured_views", r->measuredViews ? r->measuredViews : int(r->views.size())},
                      {"fingerprint", r->fingerprintCheck},
                      {"data", base64Encode(r->srgb.data(), r->srgb.size())}};
  }
  std::string data = d.dump();
  // Inside <script>: "</" would end the element early; "<\/" is the same JSON string.
  for (std::size_t at = data.find("</"); at != std::string::npos; at = data.find("</", at + 3)) data.replace(at, 2, "<\\/");
  std::string page = kPage;
  const std::string marker = "@NBTF_DATA@";
  page.replace(page.find(marker), marker.size(), data);
  return page;
}

}  // namespace nbtf
