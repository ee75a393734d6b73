"""The reproducibility floor: how far a twin diverges from itself, and divergences judged against it.

A pole released near its unstable equilibrium that lands on a hard stop is chaotic: moving its initial
angle by 1 µrad changes where inside an ODE step the impact falls, hence the kick to the cart and every
bounce after. No second engine can be expected to agree with a twin more closely than the twin agrees with
itself under such a shift. So a divergence between two twins is judged against each side's **floor** (its
ensemble members, `dualtwin.suite.ensemble`, against its unperturbed member 0), and the **floor ratio**
(divergence ÷ the larger floor) reads "as close as the physics allows" near 1.

The functions on arrays are pure (no I/O). `simulate_floor` runs an ensemble in memory through the shared
executor: it is the public entry point for other packages (alignment judges each fitted scenario's DTW
against it). `dualtwin.divergence.comparison` reads stored members and attaches floors to comparisons.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from dualtwin.artifacts import json_safe
from dualtwin.divergence.metrics import (
    FLOOR_RATIO_CLOSE,
    FLOOR_RATIO_NEAR,
    ChannelDivergence,
    Threshold,
    crossing_time,
    default_resolution,
    dtw_distance,
    finite_prefix,
    predictability_horizon,
    resample_common,
    rmse,
)
from dualtwin.errors import DualtwinError
from dualtwin.parallel import DEFAULT_WORKERS, ExecutorKind, ParallelMap
from dualtwin.robots.binding import RobotBinding

#: The pole-fall threshold runs use on ``*_angle_rad`` channels (see `dualtwin.divergence.comparison`).
DEFAULT_ANGLE_THRESHOLD_RAD = 0.99


@dataclass(frozen=True)
class ChannelFloor:
    """The reproducibility floor of one channel in one scenario: a twin's members against its member 0.

    Divergences are means over members 1..N-1 of the metric between member 0 (unperturbed) and member k,
    each on their common grid, so a floor reads on the same scale as a divergence between two twins.

    Attributes:
        members: Members used (member 0 included).
        rmse: Mean RMSE against member 0.
        rmse_max: Largest RMSE against member 0: what the twin cannot reproduce at worst. Significance is
            measured against it, so a second engine that behaves like one more member never ranks.
        dtw: Mean DTW (dtaidistance's value) against member 0.
        dtw_rms: Mean ``dtw / sqrt(n)``.
        max_abs_error: Largest ``|member k - member 0|`` over members and time.
        crossing_spread_s: Largest minus smallest threshold-crossing time among the members; None without a
            threshold or when no member crosses; inf when only some cross.
        spread: Largest spread (max - min over members at one time) on the common grid.
        horizon_s: First time the spread exceeds the resolution: where the trajectories stop being
            predictable (for a falling pole, its first impact); None if they never do.
    """

    members: int
    rmse: float
    rmse_max: float
    dtw: float
    dtw_rms: float
    max_abs_error: float
    crossing_spread_s: float | None
    spread: float
    horizon_s: float | None

    def to_dict(self) -> dict[str, Any]:
        return json_safe(asdict(self))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ChannelFloor:
        kwargs: dict[str, Any] = {f.name: data.get(f.name) for f in fields(cls)}
        return cls(**kwargs)


def ensemble_floor(
    members: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    resolution: float,
    threshold: float | Threshold | None = None,
    dtw_window: int | None = None,
) -> ChannelFloor:
    """The reproducibility floor of one channel from its ensemble members (member 0 first, unperturbed).

    Raises:
        ValueError: With fewer than 2 members, or a member with fewer than 2 finite samples.
    """
    if len(members) < 2:
        raise ValueError(f"a floor needs at least 2 members, got {len(members)}")
    series = [finite_prefix(t, y) for t, y in members]
    t0, y0 = series[0]
    rmses, dtws, dtw_rmss, maxabs = [], [], [], []
    for tk, yk in series[1:]:
        common = resample_common(t0, y0, tk, yk)
        rmses.append(rmse(common.a, common.b))
        d = dtw_distance(common.a, common.b, window=dtw_window)
        dtws.append(d.distance)
        dtw_rmss.append(d.rms)
        maxabs.append(float(np.max(np.abs(common.b - common.a))))
    # Spread on member 0's samples over the span every member covers.
    end = min(float(tk[-1]) for tk, _ in series)
    start = max(float(tk[0]) for tk, _ in series)
    keep = (t0 >= start - 1e-9) & (t0 <= end + 1e-9)
    grid = t0[keep]
    stacked = np.vstack([np.interp(grid, tk, yk) for tk, yk in series])
    spread, horizon = predictability_horizon(grid, stacked, resolution) if grid.size else (0.0, None)
    spread_s: float | None = None
    if threshold is not None:
        crossings = [crossing_time(tk, yk, threshold) for tk, yk in series]
        hit = [c for c in crossings if c is not None]
        if hit:
            spread_s = max(hit) - min(hit) if len(hit) == len(crossings) else math.inf
    return ChannelFloor(members=len(series), rmse=float(np.mean(rmses)), rmse_max=float(max(rmses)),
                        dtw=float(np.mean(dtws)),
                        dtw_rms=float(np.mean(dtw_rmss)), max_abs_error=float(max(maxabs)),
                        crossing_spread_s=spread_s, spread=spread, horizon_s=horizon)


@dataclass(frozen=True)
class FloorJudgement:
    """A divergence between two twins judged against their reproducibility floors (one channel, one scenario).

    Attributes:
        floor_a: Twin A's floor (None: A is no ensemble).
        floor_b: Twin B's floor.
        floor_dtw: The larger DTW floor of the two.
        floor_rmse: The larger RMSE floor of the two.
        floor_rmse_max: The larger worst-member RMSE of the two (what significance is measured against).
        ratio: DTW between the twins ÷ ``floor_dtw`` (None when the floor is 0).
        ratio_rmse: RMSE between the twins ÷ ``floor_rmse``.
        horizon_s: The earlier predictability horizon of the two sides.
        verdict: The ratio in words.
    """

    floor_a: ChannelFloor | None
    floor_b: ChannelFloor | None
    floor_dtw: float
    floor_rmse: float
    floor_rmse_max: float
    ratio: float | None
    ratio_rmse: float | None
    horizon_s: float | None
    verdict: str

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["floor_a"] = None if self.floor_a is None else self.floor_a.to_dict()
        out["floor_b"] = None if self.floor_b is None else self.floor_b.to_dict()
        return json_safe(out)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> FloorJudgement:
        kwargs: dict[str, Any] = {f.name: data.get(f.name) for f in fields(cls)}
        for side in ("floor_a", "floor_b"):
            if kwargs[side] is not None:
                kwargs[side] = ChannelFloor.from_dict(kwargs[side])
        return cls(**kwargs)


def floor_verdict(ratio: float | None, horizon_s: float | None = None, *,
                  resolution_multiple: float | None = None) -> str:
    """The floor ratio in words.

    Args:
        ratio: Divergence ÷ floor (None: the floor is 0).
        horizon_s: Where the members stop being predictable (None: they never do).
        resolution_multiple: The divergence (DTW rms) ÷ the channel's resolution. Given with no horizon, the
            scenario is predictable (members agree within the resolution), so a floor ratio would only
            measure numerical noise: the verdict reads against the resolution instead.
    """
    if horizon_s is None and resolution_multiple is not None:
        if resolution_multiple <= 1.0:
            return "agree within the channel's resolution (a predictable scenario: the members do too)"
        return (f"{resolution_multiple:.3g}× the channel's resolution in a predictable scenario (the members agree "
                "within it): a modelling difference, not chaos")
    where = "" if horizon_s is None else f"; the members stop being predictable at t = {horizon_s:.3g} s"
    if ratio is None:
        return "no reproducibility floor (the members agree exactly)" + where
    if ratio <= FLOOR_RATIO_CLOSE:
        return f"as close as the physics allows ({ratio:.2g}× the reproducibility floor)" + where
    if ratio <= FLOOR_RATIO_NEAR:
        return f"near the reproducibility floor ({ratio:.2g}×)" + where
    return f"{ratio:.3g}× the reproducibility floor: a modelling difference, not chaos" + where


def judge_against_floor(divergence: ChannelDivergence, floor_a: ChannelFloor | None,
                        floor_b: ChannelFloor | None) -> FloorJudgement:
    """Floor ratio of a divergence between two twins: its DTW ÷ the larger of the two sides' DTW floors.

    The verdict reads the ratio in words where the members stop being predictable; where they never do
    (their spread stays within the divergence's resolution) it reads the divergence against the resolution.
    """
    floors = [f for f in (floor_a, floor_b) if f is not None]
    if not floors:
        raise ValueError("judging against a floor needs at least one side's floor")
    floor_dtw = max(f.dtw for f in floors)
    floor_rmse = max(f.rmse for f in floors)
    horizons = [f.horizon_s for f in floors if f.horizon_s is not None]
    horizon = min(horizons) if horizons else None
    ratio = divergence.dtw / floor_dtw if floor_dtw > 0 else None
    ratio_rmse = divergence.rmse / floor_rmse if floor_rmse > 0 else None
    multiple = None if divergence.resolution is None else divergence.dtw_rms / divergence.resolution
    return FloorJudgement(floor_a=floor_a, floor_b=floor_b, floor_dtw=floor_dtw, floor_rmse=floor_rmse,
                          floor_rmse_max=max(f.rmse_max for f in floors),
                          ratio=ratio, ratio_rmse=ratio_rmse, horizon_s=horizon,
                          verdict=floor_verdict(ratio, horizon, resolution_multiple=multiple))


def simulate_floor(
    robot: RobotBinding,
    twin: str,
    suite_path: Path,
    perturb: Mapping[str, float],
    *,
    members: int = 5,
    seed: int = 0,
    scenarios: Sequence[str] | None = None,
    channels: Sequence[str] | None = None,
    thresholds: Mapping[str, float | Threshold] | None = None,
    resolutions: Mapping[str, float] | None = None,
    executor: ExecutorKind | ParallelMap = "process",
    workers: int = DEFAULT_WORKERS,
) -> dict[str, dict[str, ChannelFloor]]:
    """The reproducibility floor of ``twin`` per scenario and channel, from an ensemble run in memory.

    This is the function to call for "within k× its floor" goals: e.g.
    ``simulate_floor(robot, "webots", suite, {"initial_angle": 1e-6})["00_Step_Response"]["pole_angle_rad"].dtw``.

    Args:
        robot: The robot binding.
        twin: Twin name (``mujoco``, ``webots``).
        suite_path: Suite file.
        perturb: Initial-condition key -> largest shift (see `dualtwin.suite.ensemble.EnsembleSpec`).
        members: Ensemble size, the unperturbed member included (>= 2).
        seed: Run seed, also seeding the shifts of members 3 and up.
        scenarios: Scenario ids (all if None).
        channels: Channel names (all the binding logs if None).
        thresholds: Crossing thresholds per channel (default: 0.99 rad on ``*_angle_rad`` channels).
        resolutions: Resolution per channel (default: the binding's, else by unit).
        executor: ``process``, ``serial``, ``ray`` or an existing `ParallelMap`.
        workers: Process-pool size.

    Raises:
        DualtwinError: On an unknown key, scenario or channel.
    """
    # Imported here: the suite runner pulls in the twins, which readers of stored runs never need.
    from dualtwin.suite.ensemble import make_spec, simulate_members

    spec = make_spec(members, dict(perturb), robot, seed)
    runs = simulate_members(spec, robot, twin, Path(suite_path), seed=seed, scenarios=scenarios,
                            executor=executor, workers=workers)
    info = channel_resolutions(robot)
    names = list(info) if channels is None else list(channels)
    unknown = sorted(set(names) - set(info))
    if unknown:
        raise DualtwinError(f"unknown channels {unknown}; robot {robot.name!r} logs {sorted(info)}")
    onboard, truth = list(robot.spec.onboard), list(robot.spec.ground_truth)
    out: dict[str, dict[str, ChannelFloor]] = {}
    for sid in runs[0]:
        per: dict[str, ChannelFloor] = {}
        for name in names:
            is_onboard = name.startswith("onboard/")
            columns = onboard if is_onboard else truth
            col = 1 + columns.index(name.removeprefix("onboard/"))
            series = []
            for run in runs:
                rows = run[sid].onboard if is_onboard else run[sid].ground_truth
                data = np.asarray(rows, dtype=np.float64).reshape(-1, 1 + len(columns))
                series.append((data[:, 0], data[:, col]))
            if any(t.size < 2 for t, _ in series):
                continue  # a member that ended at once (unstable) has no trajectory to compare
            threshold = (thresholds or {}).get(name, DEFAULT_ANGLE_THRESHOLD_RAD if name.endswith("_angle_rad")
                                               else None)
            per[name] = ensemble_floor(series, resolution=(resolutions or {}).get(name, info[name]),
                                       threshold=threshold)
        out[sid] = per
    return out


def channel_resolutions(robot: RobotBinding) -> dict[str, float]:
    """Every logged channel's resolution, named as in run manifests: the binding's, else by unit."""
    out: dict[str, float] = {}
    for name, channel in robot.spec.ground_truth.items():
        out[name] = channel.resolution if channel.resolution is not None else default_resolution(channel.unit)
    for name, channel in robot.spec.onboard.items():
        value = channel.resolution if channel.resolution is not None else default_resolution(channel.unit)
        out[f"onboard/{name}"] = value
    return out
