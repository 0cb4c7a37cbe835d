#!/usr/bin/env python3
"""The exported decoder shader on a native OpenGL ES 3 driver, without a display or a browser.

`nbtf export-shader` writes GLSL ES 3.00; `tests/viewer_browser_test.cpp` checks it in WebGL2
(Chromium on SwiftShader). This script runs the same export through EGL and OpenGL ES 3.0 by
ctypes alone (numpy is the only module it needs), so it checks a GPU's own compiler and measures
a GPU's frame time (docs/shader.md, *On a native driver*):

  prepare FILE.nbtf OUT [--weights W]
                          (needs the nbtf module, PYTHONPATH=build/python, and the nbtf binary
                          in $NBTF_BIN_DIR, default build/bin) exports the shader
                          into OUT/export and writes OUT/reference.npz: the file decoded by
                          the C++ decoder at every texel for a few (light, view) pairs.
  run OUT [--size N] [--frames F] [--stage fragment|compute] [--json PATH]
                          renders the texel grid at each pair into a float32 framebuffer, reads
                          it back, compares with the reference (linear RGB, the decoder's
                          output times alpha), then times F frames of N x N pixels that all
                          decode (default 1024, 50), and prints a JSON summary. --stage
                          compute calls the function from a GLES 3.1 compute shader instead.

EGL: the default display, else the first EGL device (EGL_EXT_platform_device), else Mesa's
surfaceless platform; set __EGL_VENDOR_LIBRARY_FILENAMES to pick a vendor. Exit status 1 when
the comparison fails (any value off by more than --tolerance, default 1e-3 of the reference's
largest value), 2 on a usage or driver error.
"""
import argparse
import ctypes
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np

# (light, view) pairs as (theta, phi) in degrees: measured-grid ones and ones between them.
PAIRS = [((0, 0), (0, 0)), ((30, 60), (45, 180)), ((37.5, 200), (10, 45)), ((75, 345), (60, 120)),
         ((52, 10), (22, 290))]


def unit(theta_phi):
    t, p = np.radians(theta_phi[0]), np.radians(theta_phi[1])
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], dtype=np.float64)


def prepare(args):
    import nbtf  # the project's module; only this step needs it
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    nbtf_bin = os.path.join(os.environ.get("NBTF_BIN_DIR", os.path.join(root, "build", "bin")), "nbtf")
    os.makedirs(args.out, exist_ok=True)
    subprocess.run([nbtf_bin, "export-shader", args.file, "-o", os.path.join(args.out, "export"), "--weights",
                    args.weights, "-q"], check=True)
    m = nbtf.open(args.file)
    width, height = m.width, m.height
    ys, xs = np.mgrid[0:height, 0:width]
    texels = np.stack([xs.ravel(), ys.ravel()], axis=1)
    images = []
    for light, view in PAIRS:
        rgb = m.query(texel=texels, light=unit(light), view=unit(view))
        images.append(np.asarray(rgb, dtype=np.float32).reshape(height, width, 3))
    np.savez(os.path.join(args.out, "reference.npz"), images=np.stack(images),
             lights=np.array([unit(l) for l, _ in PAIRS], dtype=np.float32),
             views=np.array([unit(v) for _, v in PAIRS], dtype=np.float32),
             source=os.path.basename(args.file))
    print(f"prepared {args.out}: {width} x {height} texels, {len(PAIRS)} pairs")


# ---- EGL and GLES by ctypes ------------------------------------------------------------------
EGL_NONE, EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE = 0x3038, 0x3033, 0x0001, 0x3040
EGL_OPENGL_ES3_BIT, EGL_CONTEXT_MAJOR_VERSION, EGL_OPENGL_ES_API = 0x0040, 0x3098, 0x30A0
EGL_PLATFORM_DEVICE_EXT, EGL_PLATFORM_SURFACELESS_MESA = 0x313F, 0x31DD
GL_VERTEX_SHADER, GL_FRAGMENT_SHADER, GL_COMPILE_STATUS, GL_LINK_STATUS = 0x8B31, 0x8B30, 0x8B81, 0x8B82
GL_TEXTURE_2D, GL_TEXTURE0, GL_TEXTURE_MIN_FILTER, GL_TEXTURE_MAG_FILTER, GL_NEAREST = 0x0DE1, 0x84C0, 0x2801, 0x2800, 0x2600
GL_RGBA32F, GL_RGBA, GL_FLOAT, GL_UNIFORM_BUFFER, GL_STATIC_DRAW = 0x8814, 0x1908, 0x1406, 0x8A11, 0x88E4
GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_FRAMEBUFFER_COMPLETE, GL_TRIANGLES = 0x8D40, 0x8CE0, 0x8CD5, 0x0004
GL_RENDERER, GL_VERSION, GL_UNPACK_ALIGNMENT, GL_PACK_ALIGNMENT = 0x1F01, 0x1F02, 0x0CF5, 0x0D05


class DriverError(Exception):
    pass


def load(names):
    for name in names:
        try:
            return ctypes.CDLL(name)
        except OSError:
            pass
    raise DriverError(f"none of {', '.join(names)} could be loaded")


class Gles:
    """A surfaceless OpenGL ES 3 context; attribute access returns GL functions."""

    def __init__(self):
        egl = load(["libEGL.so.1", "libEGL.so"])
        self.gl = load(["libGLESv2.so.2", "libGLESv2.so"])
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        egl.eglGetDisplay.restype = ctypes.c_void_p
        egl.eglGetDisplay.argtypes = [ctypes.c_void_p]
        for f in ("eglInitialize", "eglChooseConfig", "eglBindAPI", "eglMakeCurrent"):
            getattr(egl, f).restype = ctypes.c_uint
        egl.eglInitialize.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
        egl.eglChooseConfig.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int,
                                        ctypes.POINTER(ctypes.c_int)]
        egl.eglCreateContext.restype = ctypes.c_void_p
        egl.eglCreateContext.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
        egl.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
        self.egl = egl
        self.display, self.platform = self._display()
        egl.eglBindAPI(EGL_OPENGL_ES_API)
        config = ctypes.c_void_p()
        count = ctypes.c_int()
        for surface in (0, EGL_PBUFFER_BIT):  # no surface is drawn to: any kind will do
            attributes = (ctypes.c_int * 5)(EGL_RENDERABLE_TYPE, EGL_OPENGL_ES3_BIT, EGL_SURFACE_TYPE, surface, EGL_NONE)
            if egl.eglChooseConfig(self.display, attributes, ctypes.byref(config), 1, ctypes.byref(count)) and count.value:
                break
        else:
            raise DriverError("eglChooseConfig found no OpenGL ES 3 configuration")
        context_attributes = (ctypes.c_int * 3)(EGL_CONTEXT_MAJOR_VERSION, 3, EGL_NONE)
        context = egl.eglCreateContext(self.display, config, None, context_attributes)
        if not context:
            raise DriverError("eglCreateContext failed for OpenGL ES 3")
        if not egl.eglMakeCurrent(self.display, None, None, context):
            raise DriverError("eglMakeCurrent without a surface failed (EGL_KHR_surfaceless_context missing?)")
        self.gl.glGetString.restype = ctypes.c_char_p
        self.renderer = self.gl.glGetString(GL_RENDERER).decode()
        self.version = self.gl.glGetString(GL_VERSION).decode()

    def _display(self):
        egl = self.egl
        major, minor = ctypes.c_int(), ctypes.c_int()
        display = egl.eglGetDisplay(None)
        if display and egl.eglInitialize(display, ctypes.byref(major), ctypes.byref(minor)):
            return display, "default"
        get_platform = egl.eglGetProcAddress(b"eglGetPlatformDisplayEXT")
        if not get_platform:
            raise DriverError("no EGL display: the default one failed and eglGetPlatformDisplayEXT is missing")
        get_platform = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_uint, ctypes.c_void_p, ctypes.c_void_p)(get_platform)
        query_devices = egl.eglGetProcAddress(b"eglQueryDevicesEXT")
        if query_devices:
            query_devices = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_int, ctypes.c_void_p,
                                             ctypes.POINTER(ctypes.c_int))(query_devices)
            devices = (ctypes.c_void_p * 8)()
            n = ctypes.c_int()
            if query_devices(8, devices, ctypes.byref(n)):
                for i in range(n.value):
                    display = get_platform(EGL_PLATFORM_DEVICE_EXT, devices[i], None)
                    if display and egl.eglInitialize(display, ctypes.byref(major), ctypes.byref(minor)):
                        return display, f"device {i}"
        display = get_platform(EGL_PLATFORM_SURFACELESS_MESA, None, None)
        if display and egl.eglInitialize(display, ctypes.byref(major), ctypes.byref(minor)):
            return display, "surfaceless"
        raise DriverError("no EGL display could be initialized (default, device, surfaceless)")

    def __getattr__(self, name):
        return getattr(self.gl, name)

    def check(self, what):
        error = self.gl.glGetError()
        if error:
            raise DriverError(f"{what}: GL error 0x{error:04x}")

    def _require(self, name, status, get_status, get_log, failure):
        """Raises DriverError(failure + the driver's log) unless get_status(name, status) is set."""
        ok = ctypes.c_int()
        get_status(name, status, ctypes.byref(ok))
        if not ok.value:
            log = ctypes.create_string_buffer(65536)
            get_log(name, len(log), None, log)
            raise DriverError(f"{failure}: {log.value.decode(errors='replace')[:4000]}")

    def shader(self, kind, source, what):
        gl = self.gl
        gl.glCreateShader.restype = ctypes.c_uint
        s = gl.glCreateShader(kind)
        text = ctypes.c_char_p(source.encode())
        gl.glShaderSource(s, 1, ctypes.byref(text), None)
        gl.glCompileShader(s)
        self._require(s, GL_COMPILE_STATUS, gl.glGetShaderiv, gl.glGetShaderInfoLog, f"{what} does not compile")
        return s

    def program(self, stages):
        """stages: (kind, source, what) of each shader; returns the linked program."""
        gl = self.gl
        gl.glCreateProgram.restype = ctypes.c_uint
        p = gl.glCreateProgram()
        for kind, source, what in stages:
            gl.glAttachShader(p, self.shader(kind, source, what))
        gl.glLinkProgram(p)
        self._require(p, GL_LINK_STATUS, gl.glGetProgramiv, gl.glGetProgramInfoLog, "the program does not link")
        return p

VERTEX = """#version 300 es
void main() { vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0); gl_Position = vec4(p, 0.0, 1.0); }"""
# Pixel (x, y) of a size-wide target decodes uv = (x + 0.5, y + 0.5) / size: at the texel
# grid's size, texel (x, y) (the viewer page's #test mode does the same).
FRAGMENT_MAIN = """
uniform vec3 uL; uniform vec3 uV; uniform vec2 uSize;
out vec4 fragColor;
void main() { fragColor = vec4(nbtf_decode(gl_FragCoord.xy / uSize, uL, uV), 1.0); }"""
PRELUDE = "#version 300 es\nprecision highp float; precision highp int; precision highp sampler2D;\n"
# --stage compute: the same function in a GLES 3.1 compute shader, one invocation per pixel. Some
# GPUs run fragment shaders on part of the chip only (NVIDIA's H100 / H200: two of their TPCs are
# graphics-capable), compute shaders on all of it.
COMPUTE_PRELUDE = "#version 310 es\nprecision highp float; precision highp int; precision highp sampler2D;\n"
COMPUTE_MAIN = """
layout(local_size_x = 8, local_size_y = 8) in;
layout(rgba32f, binding = 0) writeonly uniform highp image2D uOut;
uniform vec3 uL; uniform vec3 uV; uniform vec2 uSize;
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (float(p.x) >= uSize.x || float(p.y) >= uSize.y) return;
  imageStore(uOut, p, vec4(nbtf_decode((vec2(p) + 0.5) / uSize, uL, uV), 1.0));
}"""
GL_COMPUTE_SHADER, GL_WRITE_ONLY, GL_ALL_BARRIER_BITS = 0x91B9, 0x88B9, 0xFFFFFFFF


def bind_export(gl, program, folder, manifest):
    """Textures and uniform blocks as manifest.json lists them (docs/shader.md)."""
    gl.glUseProgram(program)
    gl.glGetUniformLocation.restype = ctypes.c_int
    gl.glGetUniformBlockIndex.restype = ctypes.c_uint
    gl.glPixelStorei(GL_UNPACK_ALIGNMENT, 4)
    for unit, t in enumerate(manifest["textures"]):
        data = np.fromfile(os.path.join(folder, t["file"]), dtype="<f4")
        if data.size != t["width"] * t["height"] * 4:
            raise DriverError(f"{t['file']}: {data.size} floats, the manifest says {t['width']} x {t['height']} x 4")
        name = ctypes.c_uint()
        gl.glGenTextures(1, ctypes.byref(name))
        gl.glActiveTexture(GL_TEXTURE0 + unit)
        gl.glBindTexture(GL_TEXTURE_2D, name)
        gl.glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST)
        gl.glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST)
        gl.glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, t["width"], t["height"], 0, GL_RGBA, GL_FLOAT,
                        data.ctypes.data_as(ctypes.c_void_p))
        gl.glUniform1i(gl.glGetUniformLocation(program, t["uniform"].encode()), unit)
        gl.check(f"texture {t['uniform']}")
    for binding, b in enumerate(manifest.get("uniform_blocks", [])):
        data = np.fromfile(os.path.join(folder, b["file"]), dtype="<f4")
        buffer = ctypes.c_uint()
        gl.glGenBuffers(1, ctypes.byref(buffer))
        gl.glBindBuffer(GL_UNIFORM_BUFFER, buffer)
        gl.glBufferData(GL_UNIFORM_BUFFER, ctypes.c_ssize_t(data.nbytes), data.ctypes.data_as(ctypes.c_void_p),
                        GL_STATIC_DRAW)
        gl.glBindBufferBase(GL_UNIFORM_BUFFER, binding, buffer)
        gl.glUniformBlockBinding(program, gl.glGetUniformBlockIndex(program, b["block"].encode()), binding)
        gl.check(f"uniform block {b['block']}")


def target(gl, width, height, compute):
    """A float32 RGBA texture of width x height, bound as the framebuffer (reads come from it)
    and, for compute, as image unit 0."""
    texture, framebuffer = ctypes.c_uint(), ctypes.c_uint()
    gl.glGenTextures(1, ctypes.byref(texture))
    gl.glActiveTexture(GL_TEXTURE0 + 31)
    gl.glBindTexture(GL_TEXTURE_2D, texture)
    gl.glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA32F, width, height)  # immutable: image units need it
    if compute:
        gl.glBindImageTexture(0, texture, 0, 0, 0, GL_WRITE_ONLY, GL_RGBA32F)
    gl.glGenFramebuffers(1, ctypes.byref(framebuffer))
    gl.glBindFramebuffer(GL_FRAMEBUFFER, framebuffer)
    gl.glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, texture, 0)
    gl.glCheckFramebufferStatus.restype = ctypes.c_uint
    if gl.glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE:
        raise DriverError("an RGBA32F framebuffer is not renderable here (EXT_color_buffer_float missing?)")
    gl.glViewport(0, 0, width, height)
    return framebuffer


def draw(gl, program, light, view, width, height, compute):
    gl.glUniform3f(gl.glGetUniformLocation(program, b"uL"), *map(ctypes.c_float, light))
    gl.glUniform3f(gl.glGetUniformLocation(program, b"uV"), *map(ctypes.c_float, view))
    gl.glUniform2f(gl.glGetUniformLocation(program, b"uSize"), ctypes.c_float(width), ctypes.c_float(height))
    if compute:
        gl.glDispatchCompute((width + 7) // 8, (height + 7) // 8, 1)
        gl.glMemoryBarrier(GL_ALL_BARRIER_BITS)
    else:
        gl.glDrawArrays(GL_TRIANGLES, 0, 3)


def run(args):
    folder = os.path.join(args.out, "export")
    manifest = json.load(open(os.path.join(folder, "manifest.json")))
    reference = np.load(os.path.join(args.out, "reference.npz"))
    glsl = open(os.path.join(folder, manifest["glsl"])).read()
    gl = Gles()
    compute = args.stage == "compute"
    if compute:
        program = gl.program([(GL_COMPUTE_SHADER, COMPUTE_PRELUDE + glsl + COMPUTE_MAIN, "the decoder's compute shader")])
    else:
        program = gl.program([(GL_VERTEX_SHADER, VERTEX, "the vertex shader"),
                              (GL_FRAGMENT_SHADER, PRELUDE + glsl + FRAGMENT_MAIN, "the decoder's fragment shader")])
    bind_export(gl, program, folder, manifest)
    vao = ctypes.c_uint()
    gl.glGenVertexArrays(1, ctypes.byref(vao))
    gl.glBindVertexArray(vao)
    material = manifest["material"]
    width, height = material["width"], material["height"]
    images = reference["images"]
    scale = float(np.abs(images).max())
    worst = 0.0
    target(gl, width, height, compute)
    gl.glPixelStorei(GL_PACK_ALIGNMENT, 4)
    for i in range(images.shape[0]):
        draw(gl, program, reference["lights"][i], reference["views"][i], width, height, compute)
        pixels = np.empty((height, width, 4), dtype=np.float32)
        gl.glReadPixels(0, 0, width, height, GL_RGBA, GL_FLOAT, pixels.ctypes.data_as(ctypes.c_void_p))
        gl.check(f"pair {i}")
        worst = max(worst, float(np.abs(pixels[..., :3] - images[i]).max()))
    # Timing: every pixel of an N x N target decodes (the texel grid stretched over it).
    target(gl, args.size, args.size, compute)
    light, view = reference["lights"][1], reference["views"][1]
    draw(gl, program, light, view, args.size, args.size, compute)  # warm-up: the driver's lazy work
    gl.glFinish()
    times = []
    for _ in range(args.frames):
        t0 = time.perf_counter()
        draw(gl, program, light, view, args.size, args.size, compute)
        gl.glFinish()
        times.append(time.perf_counter() - t0)
    gl.check("timed frames")
    median = statistics.median(times)
    cost = manifest.get("cost_per_pixel", {})
    summary = {
        "renderer": gl.renderer, "stage": args.stage, "gl_version": gl.version, "egl_display": gl.platform,
        "source": str(reference["source"]), "method": material["method"], "texels": [width, height],
        "weights": manifest.get("weights"), "pairs": int(images.shape[0]),
        "max_abs_difference": worst, "reference_max": scale,
        "tolerance": args.tolerance * scale, "pass": worst <= args.tolerance * scale,
        "frame_pixels": args.size * args.size, "frames": args.frames,
        "frame_ms_median": 1e3 * median, "frame_ms_min": 1e3 * min(times),
        "decodes_per_second": args.size * args.size / median,
        "operations_per_pixel": cost.get("operations"),
        "arithmetic_tflops": (2 * cost["operations"] * args.size * args.size / median / 1e12) if "operations" in cost else None,
    }
    text = json.dumps(summary, indent=1)
    print(text)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text + "\n")
    return 0 if summary["pass"] else 1


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("prepare")
    p.add_argument("file")
    p.add_argument("out")
    p.add_argument("--weights", default="auto", help="export-shader's --weights: auto, texture, uniform-blocks")
    r = sub.add_parser("run")
    r.add_argument("out")
    r.add_argument("--size", type=int, default=1024)
    r.add_argument("--frames", type=int, default=50)
    r.add_argument("--tolerance", type=float, default=1e-3)
    r.add_argument("--json")
    r.add_argument("--stage", choices=["fragment", "compute"], default="fragment")
    args = parser.parse_args()
    try:
        return prepare(args) if args.command == "prepare" else run(args)
    except (DriverError, OSError, KeyError) as e:
        print(f"shader_native.py: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main() or 0)
