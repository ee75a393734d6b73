"""Headless by default: pick MuJoCo's offscreen OpenGL backend before MuJoCo is imported.

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is first imported. Left unset on a machine without a display it
picks GLFW, which cannot open a window; the first render then fails, and under Gymnasium's ``check_env`` the
interpreter can even abort. So ``import dualtwin`` (which runs before any dualtwin module imports MuJoCo) calls
:func:`choose_gl_backend`, which decides once per process:

* ``MUJOCO_GL`` already set: the user's choice, left alone.
* A display (``DISPLAY`` or ``WAYLAND_DISPLAY``) present, or not Linux: MuJoCo's own default, left alone.
* Otherwise EGL if it really initialises (Mesa's software EGL works without a GPU), else OSMesa if its library
  loads. The probe runs in a short child process (about 30 ms): a broken driver can crash the process that
  loads it, and the probe must not leave an EGL display or a loaded driver behind in ours. ``MUJOCO_GL`` and
  ``PYOPENGL_PLATFORM`` are then set together (MuJoCo refuses a ``PYOPENGL_PLATFORM`` that disagrees), so child
  processes inherit the choice and do not probe again.

Decisions: the probe does not import MuJoCo (that would fix the backend before it is chosen); it mirrors what
MuJoCo's EGL backend does (a display on an EGL *device*, ``EGL_EXT_platform_device``, then ``eglInitialize``).
If neither backend works, ``MUJOCO_GL=egl`` is still set: rendering then fails with a clear error at the first
frame (instead of GLFW aborting), and everything that does not render works. :func:`gl_backend` says what was
chosen and why (``dualtwin --verbose`` prints it).
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import json
import os
import re
import subprocess
import sys
import types
from collections.abc import Sequence
from dataclasses import dataclass

BACKENDS = ("egl", "osmesa")

# Runs in a child interpreter (-I -S: no site packages, no user paths, so it starts in milliseconds).
_PROBE = r"""
import ctypes, json, sys

def egl():
    try:
        lib = ctypes.CDLL("libEGL.so.1")
    except OSError as exc:
        return "libEGL.so.1 not found (" + str(exc) + ")"
    lib.eglGetProcAddress.restype = ctypes.c_void_p
    lib.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    query = lib.eglGetProcAddress(b"eglQueryDevicesEXT")
    platform = lib.eglGetProcAddress(b"eglGetPlatformDisplayEXT")
    if not query or not platform:
        return "EGL has no device platform (EGL_EXT_device_enumeration / EGL_EXT_platform_device)"
    query = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p),
                             ctypes.POINTER(ctypes.c_int))(query)
    platform = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_uint, ctypes.c_void_p, ctypes.c_void_p)(platform)
    devices, count = (ctypes.c_void_p * 32)(), ctypes.c_int(0)
    if not query(32, devices, ctypes.byref(count)) or count.value < 1:
        return "EGL lists no devices"
    lib.eglInitialize.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int)]
    lib.eglTerminate.argtypes = [ctypes.c_void_p]
    for i in range(count.value):
        display = platform(0x313F, devices[i], None)  # EGL_PLATFORM_DEVICE_EXT
        major, minor = ctypes.c_int(0), ctypes.c_int(0)
        if display and lib.eglInitialize(display, ctypes.byref(major), ctypes.byref(minor)):
            lib.eglTerminate(display)
            return "ok: EGL %d.%d initialised on device %d of %d" % (major.value, minor.value, i, count.value)
    return "eglInitialize failed on all %d EGL devices (libegl-mesa0 / a GPU driver missing?)" % count.value

def osmesa():
    for name in ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so"):
        try:
            lib = ctypes.CDLL(name)
        except OSError:
            continue
        if hasattr(lib, "OSMesaCreateContextExt"):
            return "ok: " + name + " loads"
    return "libOSMesa not found (libosmesa6)"

result = {"egl": egl()}
if not result["egl"].startswith("ok") or "osmesa" in sys.argv[1:]:
    result["osmesa"] = osmesa()
sys.stdout.write(json.dumps(result))
"""


@dataclass(frozen=True)
class GLChoice:
    """Which offscreen backend MuJoCo will use (``backend``: egl, osmesa, or None for MuJoCo's default)."""

    backend: str | None
    reason: str
    chosen_by: str  # "user" (MUJOCO_GL was set), "dualtwin" (probed here), or "mujoco" (left to its default)

    def describe(self) -> str:
        return f"OpenGL backend: {self.backend or 'MuJoCo default'} ({self.chosen_by}: {self.reason})"


_choice: GLChoice | None = None


def probe_backends(osmesa: bool = False, timeout: float = 20.0) -> dict[str, str]:
    """Run the EGL probe (then OSMesa's, if EGL fails or ``osmesa``) in a child process.

    Each value starts with ``ok`` or says what failed.
    """
    try:
        done = subprocess.run([sys.executable, "-I", "-S", "-c", _PROBE, *(["osmesa"] if osmesa else [])],
                              capture_output=True, text=True,
                              timeout=timeout, check=False)
    except (OSError, subprocess.SubprocessError) as exc:
        return {"egl": f"probe could not run ({type(exc).__name__}: {exc})"}
    try:
        result = json.loads(done.stdout)
    except ValueError:
        result = None
    if not isinstance(result, dict):
        # The child crashed (a broken driver): exactly what running it out of process is for.
        return {"egl": f"probe exited with code {done.returncode} ({done.stderr.strip()[-200:] or 'no output'})"}
    return {str(k): str(v) for k, v in result.items()}


def choose_gl_backend() -> GLChoice:
    """Decide the backend (once per process; see the module docstring) and set the environment for it."""
    global _choice
    if _choice is not None:
        return _choice
    env = os.environ
    user = env.get("MUJOCO_GL", "").strip()
    if user:
        _choice = GLChoice(user.lower(), "MUJOCO_GL was set before dualtwin was imported", "user")
    elif "mujoco" in sys.modules:
        _choice = GLChoice(None, "mujoco was imported before dualtwin, so its backend was already fixed; set "
                                 "MUJOCO_GL=egl or osmesa before importing it on a machine without a display", "mujoco")
    elif not sys.platform.startswith("linux"):
        _choice = GLChoice(None, f"not Linux ({sys.platform}): MuJoCo's platform default", "mujoco")
    elif env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"):
        _choice = GLChoice(None, "a display is present (DISPLAY/WAYLAND_DISPLAY): MuJoCo's default (GLFW)", "mujoco")
    else:
        platform = env.get("PYOPENGL_PLATFORM", "").strip().lower()
        if platform and platform not in BACKENDS:
            _choice = GLChoice(None, f"PYOPENGL_PLATFORM={platform} is set and is neither egl nor osmesa; "
                                     "left alone", "mujoco")
        else:
            _choice = _probe_and_set(platform)
    return _choice


def _probe_and_set(platform: str) -> GLChoice:
    results = probe_backends(osmesa=platform == "osmesa")
    egl, osmesa = results.get("egl", ""), results.get("osmesa", "")
    if platform == "osmesa" and osmesa.startswith("ok"):
        backend, reason = "osmesa", f"no display; PYOPENGL_PLATFORM=osmesa was set; {osmesa}"
    elif egl.startswith("ok"):
        backend, reason = "egl", f"no display; {egl}"
    elif osmesa.startswith("ok"):
        backend, reason = "osmesa", f"no display; EGL unusable ({egl}); {osmesa}"
    else:
        backend = "egl"
        reason = (f"no display and no working offscreen backend: EGL: {egl}; OSMesa: {osmesa or 'not probed'}. "
                  "Rendering will fail; install libegl1 libegl-mesa0 libgl1-mesa-dri (or libosmesa6)")
    if platform and platform != backend:
        # MuJoCo's backend module refuses a PYOPENGL_PLATFORM that disagrees with MUJOCO_GL.
        reason += f"; PYOPENGL_PLATFORM={platform} was set and is replaced by {backend}"
    os.environ["MUJOCO_GL"] = backend
    os.environ["PYOPENGL_PLATFORM"] = backend
    return GLChoice(backend, reason, "dualtwin")


def gl_backend() -> GLChoice:
    """The offscreen OpenGL backend chosen at ``import dualtwin``, and why."""
    return choose_gl_backend()


# ------------------------------------------------------------------------------------------ MuJoCo's log file


#: How many MuJoCo warnings of one kind (the message with its numbers left out) are printed per process.
MUJOCO_WARNINGS_PER_KIND = 3
_mujoco_warning_counts: dict[str, int] = {}
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _mujoco_warning(message: str) -> None:
    # MuJoCo's default handler prints the warning and appends it to MUJOCO_LOG.TXT in the current folder, which
    # is the user's folder, not ours to write into; the message goes to stderr alone. MuJoCo warns again at every
    # step a simulation stays unstable ("... Time = 0.0020."): a model with a hostile number printed hundreds of
    # lines before the one line that says what is wrong, so each kind is printed a few times, then said once.
    kind = _NUMBER.sub("#", message)
    seen = _mujoco_warning_counts[kind] = _mujoco_warning_counts.get(kind, 0) + 1
    if seen <= MUJOCO_WARNINGS_PER_KIND:
        sys.stderr.write(f"MuJoCo warning: {message}\n")
    elif seen == MUJOCO_WARNINGS_PER_KIND + 1:
        sys.stderr.write(f"MuJoCo warning: {message} (repeated; further ones like it are not shown)\n")


def _install_mujoco_warning_handler(module: object) -> None:
    set_handler = getattr(module, "set_mju_user_warning", None)
    if set_handler is not None:
        set_handler(_mujoco_warning)


class _MujocoImportHook(importlib.abc.MetaPathFinder):
    """A meta-path finder that installs the warning handler right after ``import mujoco`` finishes, wherever in
    dualtwin (or a user's script) that import happens, without importing MuJoCo itself."""

    def find_spec(self, fullname: str, path: Sequence[str] | None, target: types.ModuleType | None = None,
                  ) -> importlib.machinery.ModuleSpec | None:
        if fullname != "mujoco":
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return None
        spec.loader = _HandlerInstallingLoader(spec.loader)
        if self in sys.meta_path:
            sys.meta_path.remove(self)  # once is enough
        return spec


class _HandlerInstallingLoader(importlib.abc.Loader):
    def __init__(self, loader: importlib.abc.Loader) -> None:
        self._loader = loader

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType | None:
        return self._loader.create_module(spec)

    def exec_module(self, module: types.ModuleType) -> None:
        self._loader.exec_module(module)
        _install_mujoco_warning_handler(module)

    def __getattr__(self, name: str) -> object:  # resource readers and the like: the real loader's
        return getattr(self._loader, name)


def route_mujoco_warnings() -> None:
    """Send MuJoCo's warnings to stderr instead of a ``MUJOCO_LOG.TXT`` in the current folder (now, or as soon
    as MuJoCo is imported). Called by ``import dualtwin``."""
    module = sys.modules.get("mujoco")
    if module is not None:
        _install_mujoco_warning_handler(module)
    elif not any(isinstance(f, _MujocoImportHook) for f in sys.meta_path):
        sys.meta_path.insert(0, _MujocoImportHook())
