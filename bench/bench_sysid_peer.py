"""dualtwin's alignment and ``mujoco.sysid`` side by side on one known-truth recording (issue 24, part 6).

Run: ``python bench/bench_sysid_peer.py`` (needs the ``sysid`` extra: ``pip install -e '.[sysid]'``).
Set ``DUALTWIN_BENCH_SYSID_PEER_OUT=DIR`` to keep the runs and ``peer.json``.

The problem both tools can solve: the bundled CartPole's MuJoCo model driven by wheel *torques*. In torque
mode the MuJoCo twin only writes the command into each wheel's ``general`` actuator (gain 1, no bias), so a
plain ``mujoco.rollout`` of ``cartpole.xml`` with the same torques held over each 32 ms control period is the
same simulation (the bench checks it: the rollout at the true values reproduces the twin's noiseless
recording to rounding error). With velocity commands the twin runs Webots' motor law, which the MJCF's own
actuators do not describe; that is why alignment does not hand its problems to ``mujoco.sysid``.

The recording: the MuJoCo twin with hidden pole damping and pole mass runs three short torque-driven scenarios; its
pole angle log gets Gaussian noise (1 % of the range) and is rounded to 3 decimals. Both tools start from the
model's nominal values (damping 0, mass 0.2 kg) within the same bounds, and see the same samples:

* the parameters are written once as a ``mujoco.sysid`` ``ParameterDict`` (names are dualtwin knob names, with
  modifiers that edit the ``MjSpec``), saved with ``save_to_disk``; dualtwin reads that file as its knob
  definitions (``AlignConfig(sysid_params=...)``, CLI ``--sysid-params``), and its exported
  ``sysid_params.yaml`` is loaded back with ``ParameterDict.load_from_disk``;
* ``mujoco.sysid``: ``optimize`` (its default ``mujoco.minimize`` backend) from the nominal values moved off
  the bounds (as its warning advises), on the pole hinge's ``qpos``; intervals from ``calculate_intervals``;
* dualtwin: ``run_align`` with least squares (basin search, the default) on ``pole_angle_rad``, serial.

Reported per tool: recovered values, 95 % intervals (and whether they hold the truth), one common criterion
(the sum of squared pole-angle errors against the recording, computed the same way for both fits and at the
truth), candidates simulated (each: all three scenarios), wall and CPU time (this process and its children).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout
from pydantic import TypeAdapter

from _common import output_folder
from dualtwin.align import AlignConfig, run_align
from dualtwin.artifacts import sha256_file, write_json
from dualtwin.robots.binding import BUNDLED, load_binding
from dualtwin.suite.runner import SuiteRun
from dualtwin.suite.signals import Signal
from dualtwin.twins import make_twin

CARTPOLE = BUNDLED / "cartpole"
PERIOD_S = 0.032
DAMPING, MASS = "joint.pole_hinge.damping", "body.pole.mass"
TRUTH = {DAMPING: 0.035, MASS: 0.26}
BOUNDS = {DAMPING: (0.0, 0.1), MASS: (0.1, 0.4)}
#: Three torque-driven scenarios with the pole free, short enough that it never reaches its stops at ±1 rad
#: (between about 0.1 and 1 rad over the whole box of bounds): an impact would make the criterion rough in the
#: knobs, and the comparison is of the tools, not of a hard problem.
SCENARIOS = [
    {"name": "Torque_Cosine", "duration_s": 1.2, "initial_angle": 0.1,
     "wheel_torque": {"kind": "sine", "amplitude": 0.1, "frequency_hz": 2.0, "phase_rad": 1.57}},
    {"name": "Torque_Cosine_Mirrored", "duration_s": 1.2, "initial_angle": -0.1,
     "wheel_torque": {"kind": "sine", "amplitude": 0.1, "frequency_hz": 2.0, "phase_rad": -1.57}},
    {"name": "Torque_Sine", "duration_s": 1.1, "initial_angle": 0.1,
     "wheel_torque": {"kind": "sine", "amplitude": 0.05, "frequency_hz": 2.0}},
]
NOISE, DECIMALS, SEED = 0.01, 3, 24
POLE = "pole_angle_rad"


def suite_file(folder: Path) -> Path:
    path = folder / "suite.json"
    path.write_text(json.dumps({"suite_name": "sysid_peer", "global_settings": {"TIME_STEP": round(PERIOD_S * 1000)},
                                "scenarios": SCENARIOS}))
    return path


def degrade(run: Path, rng: np.random.Generator) -> None:
    """Noise and rounding on every log of the recording (manifest hashes updated)."""
    manifest = json.loads((run / "manifest.json").read_text())
    for rel, entry in manifest["logs"].items():
        path = run / rel
        lines = path.read_text().splitlines()
        rows = np.array([[float(x) for x in line.split("\t")] for line in lines[1:]])
        values = rows[:, 1:]
        span = np.ptp(values, axis=0)
        values = values + rng.normal(0.0, 1.0, values.shape) * NOISE * np.where(span > 0, span, 1e-3)
        path.write_text(lines[0] + "\n" + "\n".join("\t".join([f"{r[0]:.3f}", *(f"{v:.{DECIMALS}f}" for v in vals)])
                                                     for r, vals in zip(rows, values, strict=True)) + "\n")
        entry.update({"bytes": path.stat().st_size, "sha256": sha256_file(path)})
    write_json(run / "manifest.json", manifest)


def set_damping(spec: mujoco.MjSpec, value: float) -> None:
    spec.joint("pole_hinge").damping[0] = value


def set_mass(spec: mujoco.MjSpec, value: float) -> None:
    # The pole's inertia comes from its geom (inertiafromgeom): a geom mass scales the body's mass and inertia
    # together, as dualtwin's body.<b>.mass knob does.
    spec.geom("pole_geom").mass = value


MODIFIERS = {DAMPING: set_damping, MASS: set_mass}


def sysid_parameters(sysid: Any, nominal: dict[str, float]) -> Any:
    params = sysid.ParameterDict()
    for name, (lo, hi) in BOUNDS.items():
        modifier = MODIFIERS[name]
        params.add(sysid.Parameter(name, nominal=nominal[name], min_value=lo, max_value=hi,
                                   modifier=lambda spec, p, m=modifier: m(spec, float(p.value[0]))))
    return params


def controls(scenario: dict[str, Any], timestep: float) -> tuple[np.ndarray, np.ndarray]:
    """The scenario's wheel torques at every physics step, held over each control period (as the runner does)."""
    signal = TypeAdapter(Signal).validate_python(scenario["wheel_torque"])
    per = round(PERIOD_S / timestep)
    steps = math.ceil(scenario["duration_s"] / PERIOD_S - 1e-9) * per
    t = np.arange(steps) * timestep
    u = np.array([signal((k // per) * PERIOD_S) for k in range(steps)])
    return t, np.repeat(u[:, None], 4, axis=1)


def initial_state(model: mujoco.MjModel, angle: float) -> np.ndarray:
    data = mujoco.MjData(model)
    data.qpos[model.jnt_qposadr[model.joint("pole_hinge").id]] = angle
    state = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return state


def recorded(run: Path, index: int, scenario: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    table = np.genfromtxt(run / "scenarios" / f"{index:02d}_{scenario['name']}" / "ground_truth.tsv", names=True,
                          delimiter="\t")
    return np.atleast_1d(table["time_s"]), np.atleast_1d(table[POLE])


def pole_rollout(values: dict[str, float], scenario: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """Pole angle after each physics step of ``cartpole.xml`` with ``values`` (plain mujoco.rollout)."""
    spec = mujoco.MjSpec.from_file(str(CARTPOLE / "cartpole.xml"))
    for name, value in values.items():
        MODIFIERS[name](spec, value)
    model = spec.compile()
    _, ctrl = controls(scenario, model.opt.timestep)
    state, _ = rollout.rollout(model, mujoco.MjData(model), initial_state(model, scenario["initial_angle"])[None],
                               ctrl[None])
    t = state[0, :, 0]
    return t, state[0, :, 1 + model.jnt_qposadr[model.joint("pole_hinge").id]]


def criterion(values: dict[str, float], run: Path) -> float:
    """Sum of squared pole-angle errors against the recording's samples (the same for both tools)."""
    total = 0.0
    for i, scenario in enumerate(SCENARIOS):
        t_ref, y_ref = recorded(run, i, scenario)
        t, y = pole_rollout(values, scenario)
        total += float(np.sum((np.interp(t_ref, t, y) - y_ref) ** 2))
    return total


def cpu_s() -> float:
    times = os.times()
    return times.user + times.system + times.children_user + times.children_system


def run_sysid(sysid: Any, run: Path, nominal: dict[str, float]) -> dict[str, Any]:
    spec = mujoco.MjSpec.from_file(str(CARTPOLE / "cartpole.xml"))
    model = spec.compile()
    states, ctrls, sensors, names = [], [], [], []
    for i, scenario in enumerate(SCENARIOS):
        t_ctrl, u = controls(scenario, model.opt.timestep)
        t_ref, y_ref = recorded(run, i, scenario)
        states.append(initial_state(model, scenario["initial_angle"]))
        ctrls.append(sysid.TimeSeries(t_ctrl, u))
        sensors.append(sysid.TimeSeries.from_names(t_ref, y_ref[:, None], model,
                                                   [("pole_hinge", sysid.SignalType.MjStateQPos)]))
        names.append(scenario["name"])
    sequences = sysid.ModelSequences("cartpole", spec, names, states, ctrls, sensors, allow_missing_sensors=True)
    evaluations = [0]

    def build(params: Any, spec_: mujoco.MjSpec) -> mujoco.MjModel:
        evaluations[0] += 1
        return sysid.apply_param_modifiers(params, spec_)

    residual_fn = sysid.build_residual_fn(models_sequences=[sequences], build_model=build)
    params = sysid_parameters(sysid, nominal).move_off_bounds()
    start, cpu = time.perf_counter(), cpu_s()
    fitted, result = sysid.optimize(params, residual_fn, optimizer="mujoco", verbose=False)
    wall, cpu = time.perf_counter() - start, cpu_s() - cpu
    # One model is built per scenario and candidate: candidates = builds / scenarios (as dualtwin's suite runs).
    candidates = evaluations[0] // len(SCENARIOS)
    residuals, _, _ = residual_fn(fitted.as_vector(), fitted)
    _, half = sysid.calculate_intervals(residuals, result.jac)
    values = {name: float(fitted[name].value[0]) for name in BOUNDS}
    return {"values": values, "half_width_95": dict(zip(BOUNDS, map(float, half), strict=True)),
            "intervals": {n: [values[n] - float(h), values[n] + float(h)] for n, h in zip(BOUNDS, half, strict=True)},
            "method": "Jacobian at the end, i.i.d. residuals (calculate_intervals)",
            "wall_s": wall, "cpu_s": cpu, "candidates": candidates,
            "start": {n: float(params[n].value[0]) for n in BOUNDS}}


def run_dualtwin(root: Path, run: Path, suite: Path, params_file: Path) -> dict[str, Any]:
    config = AlignConfig(reference=str(run), target="mujoco", robot="cartpole", suite=str(suite), knobs=[],
                         sysid_params=str(params_file), channels=[POLE], optimizer="lsq", budget=120,
                         executor="serial", seed=0)
    out = root / "dualtwin_fit"
    shutil.rmtree(out, ignore_errors=True)
    start, cpu = time.perf_counter(), cpu_s()
    result = run_align(config, out)
    wall, cpu = time.perf_counter() - start, cpu_s() - cpu
    values = {n: result.knobs[n].fitted for n in BOUNDS}
    intervals = {n: list(result.knobs[n].interval_95 or (-math.inf, math.inf)) for n in BOUNDS}
    return {"values": values, "intervals": intervals, "methods": {n: result.knobs[n].method for n in BOUNDS},
            "wall_s": wall, "cpu_s": cpu, "suite_runs": result.evaluations, "stop": result.stop_reason,
            "exported": out / "sysid_params.yaml"}


def main() -> dict[str, Any]:
    from mujoco import sysid  # the optional extra: ImportError here says what to install

    if not hasattr(sysid, "optimize"):
        raise SystemExit("mujoco.sysid is installed without its optional dependencies: pip install -e '.[sysid]'")
    with output_folder("DUALTWIN_BENCH_SYSID_PEER_OUT", "sysid-peer") as (root, _):
        robot = load_binding(CARTPOLE / "binding.yaml")
        suite = suite_file(root)
        twin = make_twin("mujoco", robot, PERIOD_S)
        nominal = {n: twin.knobs()[n].nominal for n in BOUNDS}
        twin.set_knobs(TRUTH)
        run = root / "recording"
        shutil.rmtree(run, ignore_errors=True)
        SuiteRun(suite, "mujoco", robot, run, twin=twin).run()
        twin.close()
        print("== dualtwin align and mujoco.sysid on one known-truth recording (CartPole, MuJoCo, wheel torques) ==")
        same = criterion(TRUTH, run)
        print(f"   same simulation: the plain rollout of cartpole.xml at the truth vs the twin's recording: "
              f"sum of squared pole-angle differences {same:.1e} rad²")
        degrade(run, np.random.default_rng(SEED))
        params_file = root / "sysid_params_in.yaml"
        sysid_parameters(sysid, nominal).save_to_disk(params_file)

        theirs = run_sysid(sysid, run, nominal)
        ours = run_dualtwin(root, run, suite, params_file)
        exported = sysid.ParameterDict.load_from_disk(ours.pop("exported"))
        round_trip = {n: float(exported[n].value[0]) for n in BOUNDS}
        assert all(math.isclose(round_trip[n], ours["values"][n]) for n in BOUNDS), round_trip
        rows: dict[str, Any] = {"truth": TRUTH, "nominal": nominal, "criterion_truth": criterion(TRUTH, run),
                                "criterion_nominal": criterion(nominal, run)}
        for label, r in (("mujoco.sysid", theirs), ("dualtwin align", ours)):
            r["criterion"] = criterion(r["values"], run)
            r["covered"] = {n: bool(r["intervals"][n][0] <= TRUTH[n] <= r["intervals"][n][1]) for n in BOUNDS}
            rows[label] = r
        print(f"\n{'':<16}{'damping (N·m·s/rad)':<36}{'pole mass (kg)':<32}{'criterion':>11}{'evals':>7}"
              f"{'wall s':>8}{'CPU s':>8}")
        print(f"{'truth':<16}{TRUTH[DAMPING]:<36.4g}{TRUTH[MASS]:<32.4g}{rows['criterion_truth']:>11.4g}")
        print(f"{'nominal (start)':<16}{nominal[DAMPING]:<36.4g}{nominal[MASS]:<32.4g}"
              f"{rows['criterion_nominal']:>11.4g}")
        for label, r in (("mujoco.sysid", theirs), ("dualtwin align", ours)):
            cells = []
            for n in BOUNDS:
                lo, hi = r["intervals"][n]
                cells.append(f"{r['values'][n]:.4g} [{lo:.4g}, {hi:.4g}] {'in' if r['covered'][n] else 'OUT'}")
            evals = r.get("candidates", r.get("suite_runs"))
            print(f"{label:<16}{cells[0]:<36}{cells[1]:<32}{r['criterion']:>11.4g}{evals:>7}{r['wall_s']:>8.1f}"
                  f"{r['cpu_s']:>8.1f}")
        print(f"\n   dualtwin interval methods: {ours['methods']}; stop: {ours['stop']}")
        print(f"   mujoco.sysid intervals: {theirs['method']}; started from {theirs['start']} (moved off the bounds)")
        print(f"   dualtwin's sysid_params.yaml loaded by ParameterDict.load_from_disk: {round_trip}")
        write_json(root / "peer.json", rows)
    return rows


if __name__ == "__main__":
    main()
