"""Import benchmark: recordings becoming run folders (``dualtwin.recorded``).

Run: ``python bench/bench_import.py`` (or ``make bench``). Two goals from the recorded-runs issue, each printed
with a baseline measured in the same run on the same files:

* a 10-minute, 100 Hz, 20-channel ROS 2 bag (MCAP, zstd chunks, written with the real ``mcap_ros2`` writer:
  ``/joint_states`` with 18 joints and ``/odom`` for x and yaw, 120,000 messages) imported in <= 5 s;
  baselines: iterating the bag's raw records with ``mcap`` (no decoding), and decoding every message with
  ``mcap_ros2`` (what any reader of these fields must do);
* a 1,000-scenario folder of the paper's logs (5 s scenarios at 32 ms, 3 decimals, 2 ms jitter) imported in
  <= 10 s; baseline: ``numpy.loadtxt`` of the same 1,000 files.

The import times include everything: validation, resampling, hashing the sources, writing and flushing the run.
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

GOALS = {"mcap_s": 5.0, "paper_s": 10.0}
MCAP_SECONDS, MCAP_HZ, MCAP_JOINTS = 600, 100, 18
PAPER_SCENARIOS = 1000


def _binding(folder: Path) -> Path:
    joints = [f"joint_{i}" for i in range(MCAP_JOINTS)]
    lines = ["name: bench_arm", "control_period_ms: 10", "twins:", "  mujoco: {model: none.xml}",
             "onboard:", "  enc_0: {sensors: [enc 0], unit: rad}", "ground_truth:"]
    lines += [f"  {j}_rad: {{joint: {j}, unit: rad}}" for j in joints]
    lines += ["  base_x_m: {body: base, axis: x, unit: m}", "  base_yaw_rad: {body: base, axis: yaw, unit: rad}"]
    path = folder / "binding.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _write_big_bag(path: Path) -> None:
    from mcap_ros2.writer import Writer

    sep = "=" * 80
    header = f"{sep}\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n{sep}\n" \
             "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
    joint_state = "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n" \
                  "float64[] effort\n" + header
    odometry = (f"std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
                f"geometry_msgs/TwistWithCovariance twist\n{sep}\nMSG: geometry_msgs/PoseWithCovariance\n"
                f"Pose pose\nfloat64[36] covariance\n{sep}\nMSG: geometry_msgs/Pose\nPoint position\n"
                f"Quaternion orientation\n{sep}\nMSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
                f"{sep}\nMSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
                f"{sep}\nMSG: geometry_msgs/TwistWithCovariance\nTwist twist\nfloat64[36] covariance\n{sep}\n"
                f"MSG: geometry_msgs/Twist\nVector3 linear\nVector3 angular\n{sep}\nMSG: geometry_msgs/Vector3\n"
                f"float64 x\nfloat64 y\nfloat64 z\n" + header)
    names = [f"joint_{i}" for i in range(MCAP_JOINTS)]
    start = 1_700_000_000_000_000_000
    zeros36 = [0.0] * 36
    with open(path, "wb") as handle:
        writer = Writer(handle)
        js = writer.register_msgdef("sensor_msgs/msg/JointState", joint_state)
        od = writer.register_msgdef("nav_msgs/msg/Odometry", odometry)
        for k in range(MCAP_SECONDS * MCAP_HZ):
            t = k / MCAP_HZ
            ns = start + k * (1_000_000_000 // MCAP_HZ) + (k * 7919 % 997) * 1000  # sub-ms jitter
            stamp = {"stamp": {"sec": ns // 10**9, "nanosec": ns % 10**9}, "frame_id": ""}
            writer.write_message("/joint_states", js, {
                "header": stamp, "name": names,
                "position": [math.sin(0.1 * (i + 1) * t) for i in range(MCAP_JOINTS)],
                "velocity": [], "effort": []}, log_time=ns, publish_time=ns)
            yaw = 0.3 * t
            writer.write_message("/odom", od, {
                "header": stamp, "child_frame_id": "base",
                "pose": {"pose": {"position": {"x": 0.2 * t, "y": 0.0, "z": 0.0},
                                  "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}},
                         "covariance": zeros36},
                "twist": {"twist": {"linear": {"x": 0.2, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.3}},
                          "covariance": zeros36}}, log_time=ns + 500, publish_time=ns + 500)
        writer.finish()


def bench_mcap(folder: Path) -> dict[str, float]:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from dualtwin.recorded import import_mcap

    binding = _binding(folder)
    suite = folder / "suite.json"
    suite.write_text(json.dumps({"suite_name": "bench", "global_settings": {"TIME_STEP": 10},
                                 "scenarios": [{"name": "ten_minutes", "duration_s": float(MCAP_SECONDS)}]}))
    bag = folder / "recording.mcap"
    t0 = time.perf_counter()
    _write_big_bag(bag)
    print(f"  wrote {bag.stat().st_size / 1e6:.1f} MB bag in {time.perf_counter() - t0:.1f} s (not timed)")
    channels = [{"name": f"joint_{i}_rad", "topic": "/joint_states", "field": "position",
                 "element": f"joint_{i}", "unit": "rad"} for i in range(MCAP_JOINTS)]
    channels += [{"name": "base_x_m", "topic": "/odom", "field": "pose.pose.position.x", "unit": "m"},
                 {"name": "base_yaw_rad", "topic": "/odom", "field": "pose.pose.orientation", "angle": "yaw",
                  "unit": "rad"}]
    mapping = folder / "mapping.yaml"
    mapping.write_text(json.dumps({"files": "recording.mcap", "channels": channels}))  # JSON is YAML

    t0 = time.perf_counter()
    with open(bag, "rb") as handle:
        raw_count = sum(1 for _ in make_reader(handle).iter_messages(log_time_order=True))
    raw = time.perf_counter() - t0
    t0 = time.perf_counter()
    with open(bag, "rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        decoded_count = sum(1 for _ in reader.iter_decoded_messages(log_time_order=True))
    decoded = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    run = import_mcap(mapping, suite, binding, folder / "run")
    imported, cpu = time.perf_counter() - t0, time.process_time() - c0
    steps = json.loads((run / "manifest.json").read_text())["scenarios"][0]["steps"]
    assert raw_count == decoded_count == 2 * MCAP_SECONDS * MCAP_HZ and steps >= MCAP_SECONDS * MCAP_HZ - 1
    return {"raw_s": raw, "decoded_s": decoded, "import_s": imported, "cpu_s": cpu}


def bench_paper(folder: Path) -> dict[str, float]:
    from dualtwin.recorded import import_paper

    rng = np.random.default_rng(0)
    logs = folder / "logs"
    logs.mkdir()
    period, duration = 0.032, 5.0
    t = np.arange(1, math.ceil(duration / period) + 1) * period
    for i in range(PAPER_SCENARIOS):
        stamps = t + rng.uniform(-0.002, 0.002, t.size)
        angle = 0.01 * (i % 7 + 1) * np.exp(t) / np.exp(duration)
        cart = 0.1 * np.sin(t + i)
        rows = "\n".join(f"{a:.3f}\t{b:.3f}\t{c:.3f}" for a, b, c in zip(stamps, angle, cart, strict=True))
        (logs / f"simulation_log_SUP_{i}.tsv").write_text("time_s\tpole_angle_rad\tcart_pos_m\n" + rows + "\n")
    suite = folder / "suite.json"
    suite.write_text(json.dumps({"suite_name": "bench_paper", "global_settings": {"TIME_STEP": 32},
                                 "scenarios": [{"name": f"s{i}", "duration_s": duration, "initial_angle": 0.01}
                                               for i in range(PAPER_SCENARIOS)]}))
    files = [logs / f"simulation_log_SUP_{i}.tsv" for i in range(PAPER_SCENARIOS)]
    t0 = time.perf_counter()
    for path in files:
        np.loadtxt(path, delimiter="\t", skiprows=1)
    baseline = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    import_paper(logs, suite, "cartpole", folder / "run")
    imported, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"loadtxt_s": baseline, "import_s": imported, "cpu_s": cpu}


def main() -> None:
    print("bench_import: recordings -> run folders (wall time is the goal; CPU time shows the share of a "
          "loaded machine)")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "mcap"
        folder.mkdir()
        m = bench_mcap(folder)
        ok = "met" if m["import_s"] <= GOALS["mcap_s"] else "NOT met"
        print(f"  MCAP 10 min x 100 Hz x 20 channels: import {m['import_s']:.2f} s (goal <= {GOALS['mcap_s']:g} s: "
              f"{ok}; CPU {m['cpu_s']:.2f} s); raw mcap read {m['raw_s']:.2f} s (import = {m['import_s'] / m['raw_s']:.1f}x), "
              f"mcap_ros2 decode {m['decoded_s']:.2f} s (import = {m['import_s'] / m['decoded_s']:.2f}x)")
        folder = Path(tmp) / "paper"
        folder.mkdir()
        p = bench_paper(folder)
        ok = "met" if p["import_s"] <= GOALS["paper_s"] else "NOT met"
        print(f"  paper format, {PAPER_SCENARIOS} scenarios: import {p['import_s']:.2f} s (goal <= "
              f"{GOALS['paper_s']:g} s: {ok}; CPU {p['cpu_s']:.2f} s); numpy.loadtxt of the same files {p['loadtxt_s']:.2f} s "
              f"(import = {p['import_s'] / p['loadtxt_s']:.1f}x)")


if __name__ == "__main__":
    main()
