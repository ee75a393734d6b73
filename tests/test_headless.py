"""Headless by default and Gymnasium registration, each in a fresh interpreter (the choice is made at import).

The children run without ``MUJOCO_GL``, ``PYOPENGL_PLATFORM`` and any display, as on a cluster node.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HEADLESS_ENV = {k: v for k, v in os.environ.items()
                if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY")}


def child(code: str, env: dict[str, str] | None = None, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], env=HEADLESS_ENV if env is None else env, cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout, check=False)


REPORT = """
import json, os, sys, dualtwin
c = dualtwin.gl_backend()
print(json.dumps({"backend": c.backend, "by": c.chosen_by, "reason": c.reason, "describe": c.describe(),
                  "MUJOCO_GL": os.environ.get("MUJOCO_GL"), "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM"),
                  "mujoco_loaded": "mujoco" in sys.modules}))
"""


def test_no_display_gets_a_working_offscreen_backend_for_gym_check_env_and_render() -> None:
    pytest.importorskip("gymnasium")
    code = """
import json, os, numpy as np
import gymnasium as gym
import dualtwin
gym.register_envs(dualtwin)
from gymnasium.utils.env_checker import check_env
choice = dualtwin.gl_backend()
env = gym.make("dualtwin/CartPole-MuJoCo-v0", render_mode="rgb_array")
check_env(env.unwrapped, skip_render_check=False)
env.reset(seed=0)
frame = np.asarray(env.render())
env.close()
print(json.dumps({"backend": choice.backend, "by": choice.chosen_by, "reason": choice.reason,
                  "MUJOCO_GL": os.environ.get("MUJOCO_GL"), "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM"),
                  "shape": list(frame.shape), "distinct": int(len(np.unique(frame.reshape(-1, 3), axis=0)))}))
"""
    done = child(code)
    if "no working offscreen backend" in done.stdout + done.stderr:
        pytest.skip("neither EGL nor OSMesa works on this machine")
    # Before the fix the child aborted (SIGABRT after GLFW failed) or raised at the first render.
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["by"] == "dualtwin" and out["backend"] in ("egl", "osmesa")
    assert out["MUJOCO_GL"] == out["PYOPENGL_PLATFORM"] == out["backend"]
    assert "no display" in out["reason"]
    assert len(out["shape"]) == 3 and out["shape"][2] == 3 and out["distinct"] > 2  # a real image, not a blank


def test_osmesa_is_the_fallback_when_egl_cannot_initialise() -> None:
    # libglvnd finds no EGL vendor through this (missing) file, so EGL lists no devices: a machine without Mesa EGL.
    env = {**HEADLESS_ENV, "__EGL_VENDOR_LIBRARY_FILENAMES": str(ROOT / "no-such-egl-vendor.json")}
    done = child(REPORT + """
import mujoco
m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><light pos="0 0 2"/>'
                                   '<geom type="sphere" size=".1" rgba="1 0 0 1"/></worldbody></mujoco>')
d = mujoco.MjData(m)
mujoco.mj_forward(m, d)
with mujoco.Renderer(m, 32, 32) as r:
    r.update_scene(d)
    print(int(r.render().max()))
""", env)
    if "libOSMesa not found" in done.stdout:
        pytest.skip("OSMesa is not installed here")
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.strip().splitlines()
    out = json.loads(lines[-2])
    assert out["backend"] == "osmesa" and out["by"] == "dualtwin" and "EGL unusable" in out["reason"]
    assert out["MUJOCO_GL"] == out["PYOPENGL_PLATFORM"] == "osmesa"
    assert int(lines[-1]) > 0  # the red sphere was drawn


@pytest.mark.parametrize(("extra", "by", "mujoco_gl"), [
    ({"MUJOCO_GL": "osmesa"}, "user", "osmesa"),  # the user's choice is never overridden
    ({"DISPLAY": ":0"}, "mujoco", None),  # with a display, MuJoCo's default stands
])
def test_user_choice_and_displays_are_left_alone(extra: dict[str, str], by: str, mujoco_gl: str | None) -> None:
    done = child(REPORT, {**HEADLESS_ENV, **extra})
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out["by"] == by and out["MUJOCO_GL"] == mujoco_gl and not out["mujoco_loaded"]


def test_import_dualtwin_does_not_import_mujoco_and_verbose_reports_the_backend() -> None:
    done = child(REPORT)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert not out["mujoco_loaded"]  # the choice is made before MuJoCo reads MUJOCO_GL
    cli = subprocess.run([sys.executable, "-c", "from dualtwin.cli import main; main()", "--verbose", "suite",
                          "validate", "--scenarios", str(ROOT / "src/dualtwin/robots/cartpole/suite.json")],
                         env=HEADLESS_ENV,
                         cwd=ROOT, capture_output=True, text=True, timeout=120, check=False)
    assert cli.returncode == 0, cli.stderr
    assert out["describe"] in cli.stderr and "OpenGL backend:" in cli.stderr


def test_gym_make_works_after_import_dualtwin_alone() -> None:
    pytest.importorskip("gymnasium")
    code = """
import sys, gymnasium as gym
try:
    gym.make("dualtwin/CartPole-MuJoCo-v0")
except gym.error.NamespaceNotFound:
    print("namespace missing before import")
import dualtwin
assert "dualtwin.rl" not in sys.modules and "mujoco" not in sys.modules  # registration is by string only
gym.register_envs(dualtwin)
env = gym.make("dualtwin/CartPole-MuJoCo-v0")
obs, _ = env.reset(seed=0)
from dualtwin.registration import ENV_IDS
missing = [i for i in ENV_IDS if i not in gym.registry]
print("ok", type(env.unwrapped).__name__, env.spec.max_episode_steps, len(obs), missing)
"""
    done = child(code)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.strip().splitlines()
    assert lines[0] == "namespace missing before import"  # the control: Gymnasium alone does not know the ids
    assert lines[-1].startswith("ok TwinEnv 1000 ") and lines[-1].endswith(" []")


def test_rl_and_registration_share_one_list_of_ids() -> None:
    pytest.importorskip("gymnasium")
    import dualtwin.registration as registration
    import dualtwin.rl as rl

    assert rl.ENV_IDS is registration.ENV_IDS
    assert set(registration.ENV_IDS) <= set(rl.registered_ids())
    assert registration.register_envs() == []  # idempotent: already registered


_UNSTABLE = """
import sys
if sys.argv[1] == "dualtwin":
    import dualtwin  # noqa: F401
import mujoco
m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><body><freejoint/><geom size=".1"/></body></worldbody></mujoco>')
d = mujoco.MjData(m)
d.qpos[0] = float("nan")
mujoco.mj_step(m, d)
"""


def test_mujoco_warnings_go_to_stderr_not_into_the_users_folder(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import subprocess
    import sys

    for who in ("dualtwin", "plain"):
        folder = tmp_path / who
        folder.mkdir()
        done = subprocess.run([sys.executable, "-c", _UNSTABLE, who], cwd=folder, capture_output=True, text=True,
                              timeout=120)
        assert done.returncode == 0, done.stderr
        if who == "dualtwin":
            assert not (folder / "MUJOCO_LOG.TXT").exists()
            assert "MuJoCo warning: Nan, Inf or huge value in QPOS" in done.stderr
        else:  # the control: MuJoCo on its own writes the file where it runs
            assert (folder / "MUJOCO_LOG.TXT").exists()


_UNSTABLE_MANY = """
import dualtwin
import mujoco
m = mujoco.MjModel.from_xml_string('<mujoco><option gravity="0 0 -1e308"/><worldbody><body><freejoint/>'
                                   '<geom size=".1"/></body></worldbody></mujoco>')
d = mujoco.MjData(m)
for _ in range(50):
    mujoco.mj_step(m, d)
"""


def test_a_warning_mujoco_repeats_every_step_is_printed_a_few_times_then_said_once() -> None:
    """A hostile model (gravity 1e308) is unstable at every step: MuJoCo warns twice a step (QACC, then QPOS
    after its reset). Before, 50 steps printed 99 lines; the error line that follows a bad input must not drown."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", _UNSTABLE_MANY], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.startswith("MuJoCo warning:")]
    for kind in ("QACC", "QPOS"):
        mine = [line for line in lines if f"Nan, Inf or huge value in {kind} at DOF 0" in line]
        assert len(mine) == 4, done.stderr
        assert "repeated" not in "".join(mine[:3]) and mine[3].endswith("(repeated; further ones like it are not shown)")
    assert len(lines) == 8, done.stderr
