"""Perception datasets (Pattern 2): camera frames paired with the supervisor's ground truth.

Layout of a dataset folder::

    manifest.json        what, how and with which versions; the list of finished shards
    shard-00000.npz      episodes 0 .. E-1   (E = episodes_per_shard)
    shard-00001.npz      episodes E .. 2E-1
    ...

Each shard is an ``.npz`` (compressed, no pickled objects) holding whole episodes, one row per frame:

==========  ===================  ================================================================
key         dtype, shape         meaning
==========  ===================  ================================================================
frames      uint8 [N, H, W, 3]   RGB camera frame, row-major from the top-left pixel
state       float32 [N, 4]       ground truth at the frame's instant: cart_position (m),
                                 cart_velocity (m/s), pole_angle (rad), pole_angular_velocity (rad/s)
time_s      float64 [N]          simulation time of the frame since the episode's reset
episode     int64 [N]            global episode index (its seed is derived from (seed, episode))
step        int64 [N]            control period index within the episode (0 = just after reset)
observation float32 [N, n_obs]   the env observation at that instant (the policy's input)
action      float32 [N, n_act]   the action applied after the frame (discrete: the index)
masks       uint8 [N, H, W, 2]   per-pixel coverage (0..255) of the pole and of the cart body, from
                                 MuJoCo's segmentation pass with the same camera (dense labels)
==========  ===================  ================================================================

Frames are taken once per control period, after the period's physics, before the next action. ``manifest.json``
records the format version, env id, twin, robot, camera spec and resolution, seed, controller (and policy
hash), the visual randomisation, state names and units, every shard's episodes, frame count and sha256, and
package versions. Shards are written atomically and the manifest is rewritten after each, so a crash keeps the
finished shards; ``collect(..., resume=True)`` continues after them. Each episode's seeds (env reset, controller,
appearance, camera jitter) derive only from ``(seed, episode)``, so resumed data equals uninterrupted data.

Every shard record lists its episodes' *identities* (``episode_ids``, see `episode_identity`): a hash of the env
id, the seed and the episode index, which fix the episode's start state, appearance and camera. A model records
the identities it trained on, and evaluation leaves those episodes out whatever dataset they arrive in (a
subset, a resumed extension, a copy), instead of trusting a whole-dataset fingerprint.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, Field, Strict, model_validator

from dualtwin.artifacts import atomic_open, package_versions, sha256_file, write_json
from dualtwin.errors import DualtwinError
from dualtwin.reporting import Progress, ProgressCallback

FORMAT = "dualtwin-perception-dataset"
FORMAT_VERSION = 1
MANIFEST = "manifest.json"
#: The state every frame is labelled with: (name, ground-truth channel of the binding, unit).
STATE = (
    ("cart_position", "cart_pos_m", "m"),
    ("cart_velocity", "cart_vel_m_s", "m/s"),
    ("pole_angle", "pole_angle_rad", "rad"),
    ("pole_angular_velocity", "pole_velocity_rad_s", "rad/s"),
)
STATE_NAMES = tuple(name for name, _, _ in STATE)
STATE_UNITS = tuple(unit for _, _, unit in STATE)
#: Bodies whose per-pixel coverage is stored in ``masks`` (binding body names, shared by both twins).
LABEL_BODIES = ("pole", "cart")
#: Camera jitter per episode when randomising: position and look-at point (m, uniform ±), fovy (deg, ±).
CAMERA_JITTER = {"pos_m": 0.02, "lookat_m": 0.02, "fovy_deg": 0.5}
COLOUR_JITTER = 0.15


KEYS = ("frames", "state", "time_s", "episode", "step", "observation", "action", "masks")
#: A count or index read from a manifest: a JSON integer (not a bool or a string), not negative.
_Count = Annotated[int, Strict(), Field(ge=0, le=2**62)]


def shard_name(index: int) -> str:
    return f"shard-{index:05d}.npz"


def episode_identity(env_id: str, seed: int, episode: int) -> str:
    """The identity of one collected episode: a hash of what fixes its start state, appearance and camera.

    Why these three: the episode's every seed derives from ``(seed, episode)`` (`episode_seeds`) and the env id
    names the twin and task; the same triple in another collection (another controller or resolution) starts
    from the same scene, so it counts as the same episode. Excluding it is the safe side of a held-out set.
    """
    import hashlib

    return hashlib.sha256(f"{env_id}|{int(seed)}|{int(episode)}".encode()).hexdigest()[:24]


def episode_identities(manifest: dict[str, Any]) -> dict[int, str]:
    """Episode index -> identity for every finished episode of a dataset manifest.

    Shards written before identities were recorded get them computed from the manifest's env id and seed.
    """
    env_id, seed = str(manifest.get("env_id")), int(manifest.get("seed", 0))
    out: dict[int, str] = {}
    for shard in manifest.get("shards", []):
        first, last = (int(v) for v in shard["episodes"])
        ids = shard.get("episode_ids") or [episode_identity(env_id, seed, e) for e in range(first, last + 1)]
        if len(ids) != last - first + 1:
            raise DualtwinError(f"shard {shard.get('file')!r}: {len(ids)} episode ids for episodes {first}..{last}")
        out.update(zip(range(first, last + 1), (str(i) for i in ids), strict=True))
    return out


def episode_seeds(seed: int, episode: int) -> dict[str, int]:
    """Independent seeds for one episode, derived only from (seed, episode): resume-safe."""
    children = np.random.SeedSequence([int(seed), int(episode)]).spawn(4)
    keys = ("env", "controller", "appearance", "camera")
    return {k: int(c.generate_state(1)[0]) for k, c in zip(keys, children, strict=True)}


def _state_reader(env: Any) -> Any:
    io = env.unwrapped.io
    names = io.ground_truth_names
    missing = [channel for _, channel, _ in STATE if channel not in names]
    if missing:
        raise DualtwinError(f"robot {io.robot.name!r}: perception labels need ground_truth channels {missing} "
                            f"(the binding has: {', '.join(names)})")
    index = [names.index(channel) for _, channel, _ in STATE]

    def read() -> np.ndarray:
        values = io.sample_ground_truth()
        return np.array([values[i] for i in index], dtype=np.float32)

    return read


def collect(env_id: str, episodes: int, out_dir: Path | str, *, controller: str = "scripted",
            policy_run: Path | str | None = None, resume: bool = False, seed: int = 0, width: int = 64,
            height: int = 64, randomize: bool = True, camera: str | None = None, max_steps: int = 250,
            episodes_per_shard: int = 10, progress: ProgressCallback | None = None) -> Path:
    """Record ``episodes`` episodes of frames + ground truth into ``out_dir`` (see the module docstring).

    Args:
        env_id: a registered dualtwin env id (its twin renders the frames).
        episodes: number of episodes in the finished dataset.
        out_dir: dataset folder; must be empty unless ``resume``.
        controller: ``scripted`` (balancing with noise), ``random`` or ``noisy-policy``.
        policy_run: the policy for ``noisy-policy`` (exported folder or training run).
        resume: continue an interrupted collection with the same settings.
        seed: base seed; episode ``e`` uses seeds derived from ``(seed, e)``.
        width, height: frame resolution.
        randomize: per-episode visual randomisation (lighting, colours, camera pose jitter).
        camera: camera name in the robot's cameras (default: ``perception``).
        max_steps: control periods per episode at most (episodes also end on termination).
        episodes_per_shard: episodes per shard file.
        progress: Called after each recorded episode (stage ``collect``).

    Returns:
        The dataset folder.
    """
    from dualtwin.perception.controllers import CONTROLLERS

    if episodes < 1 or max_steps < 1 or episodes_per_shard < 1:
        raise DualtwinError("episodes, max_steps and episodes_per_shard must be >= 1")
    if controller not in CONTROLLERS:
        raise DualtwinError(f"unknown controller {controller!r} (available: {', '.join(CONTROLLERS)})")
    out = Path(out_dir)
    created = not out.exists()
    try:
        return _collect(env_id, episodes, out, controller, policy_run, resume, seed, width, height, randomize,
                        camera, max_steps, episodes_per_shard, progress)
    except DualtwinError:
        # a refusal (a bad policy, a camera the robot lacks) leaves no folder behind; recorded shards stay
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise


def _collect(env_id: str, episodes: int, out: Path, controller: str, policy_run: Path | str | None, resume: bool,
             seed: int, width: int, height: int, randomize: bool, camera: str | None, max_steps: int,
             episodes_per_shard: int, progress: ProgressCallback | None) -> Path:
    from dualtwin.perception.controllers import make_controller
    from dualtwin.rl import make_env
    from dualtwin.twins.camera import Appearance, camera_for
    from dualtwin.twins.render import TwinCamera

    env = make_env(env_id, max_episode_steps=max_steps)
    try:
        twin_env: Any = env.unwrapped  # a dualtwin TwinEnv (twin, robot, task)
        spec = camera_for(twin_env.robot, camera).with_size(width, height)
        policy_info: dict[str, Any] | None = None
        if controller == "noisy-policy":
            if policy_run is None:
                raise DualtwinError("controller 'noisy-policy' needs policy_run")
            policy_info = {"path": str(Path(policy_run).resolve())}
        settings = {
            "format": FORMAT, "format_version": FORMAT_VERSION, "env_id": env_id, "twin": twin_env.twin_name,
            "robot": twin_env.robot_name, "camera": spec.to_dict(), "resolution": [width, height], "seed": seed,
            "controller": controller, "policy": policy_info, "max_steps": max_steps,
            "episodes_per_shard": episodes_per_shard,
            "randomization": {"enabled": randomize, "camera_jitter": CAMERA_JITTER, "colour_jitter": COLOUR_JITTER,
                              "lighting": "light gain U(0.6, 1.3), headlight U(0.3, 0.7), ambient U(0, 0.15), "
                                          "directional tilt U(-0.3, 0.3) in x and y"} if randomize
            else {"enabled": False},
            "control_period_s": twin_env.control_period,
            "state": [{"name": n, "unit": u, "channel": c} for n, c, u in STATE],
            "observation": [t.name for t in twin_env.task.observation_terms],
        }
        done = _prepare(out, settings, resume)
        n_shards = -(-episodes // episodes_per_shard)
        shards: list[dict[str, Any]] = done[:]
        if len(shards) >= n_shards and shards and shards[-1]["episodes"][1] == episodes - 1:
            _write_manifest(out, settings, shards, episodes)
            return out
        read_state = _state_reader(env)
        ctrl = make_controller(controller, env.action_space, twin_env.control_period,
                               getattr(twin_env.task, "max_cart_speed", 1.5), policy_run)
        cam = TwinCamera(twin_env.twin, spec, width, height)
        counter = Progress(progress, "collect", episodes)
        counter.done = shards[-1]["episodes"][1] + 1 if shards else 0
        try:
            for index in range(len(shards), n_shards):
                first = index * episodes_per_shard
                last = min(episodes, first + episodes_per_shard) - 1
                rows: dict[str, list[Any]] = {k: [] for k in KEYS}
                for episode in range(first, last + 1):
                    seeds = episode_seeds(seed, episode)
                    appearance = Appearance.sample(np.random.default_rng(seeds["appearance"]), COLOUR_JITTER) \
                        if randomize else None
                    episode_spec = spec.jittered(np.random.default_rng(seeds["camera"]), **CAMERA_JITTER) \
                        if randomize else spec
                    _episode(env, ctrl, cam, episode_spec, appearance, read_state, seeds, episode, rows)
                    counter.advance(message=f"{len(rows['frames'])} frames in this shard")
                path = out / shard_name(index)
                with atomic_open(path, "wb") as handle:
                    np.savez_compressed(
                        handle, frames=np.stack(rows["frames"]).astype(np.uint8),
                        state=np.stack(rows["state"]).astype(np.float32),
                        time_s=np.asarray(rows["time_s"], dtype=np.float64),
                        episode=np.asarray(rows["episode"], dtype=np.int64),
                        step=np.asarray(rows["step"], dtype=np.int64),
                        observation=np.stack(rows["observation"]).astype(np.float32),
                        action=np.stack(rows["action"]).astype(np.float32),
                        masks=np.stack(rows["masks"]).astype(np.uint8))
                shards.append({"file": path.name, "episodes": [first, last], "frames": len(rows["frames"]),
                               "sha256": sha256_file(path),
                               "episode_ids": [episode_identity(env_id, seed, e) for e in range(first, last + 1)]})
                _write_manifest(out, settings, shards, episodes)
        finally:
            cam.close()
    finally:
        env.close()
    return out


def _episode(env: Any, ctrl: Any, cam: Any, spec: Any, appearance: Any, read_state: Any, seeds: dict[str, int],
             episode: int, rows: dict[str, list[Any]]) -> None:
    twin = env.unwrapped.twin
    obs, _ = env.reset(seed=seeds["env"])
    ctrl.reset(np.random.default_rng(seeds["controller"]))
    step = 0
    while True:
        state = read_state()
        action = ctrl.act(state, obs)
        rows["frames"].append(cam.render(appearance, camera=spec))
        rows["masks"].append(cam.labels(list(LABEL_BODIES), camera=spec))
        rows["state"].append(state)
        rows["time_s"].append(twin.time)
        rows["episode"].append(episode)
        rows["step"].append(step)
        rows["observation"].append(np.asarray(obs, dtype=np.float32))
        rows["action"].append(np.asarray(action, dtype=np.float32).reshape(-1))
        obs, _, terminated, truncated, info = env.step(action)
        step += 1
        if terminated or truncated or "unstable" in info or ctrl.finished(read_state()):
            break


def _prepare(out: Path, settings: dict[str, Any], resume: bool) -> list[dict[str, Any]]:
    """The shards already finished (resume) after checking the settings match; [] for a fresh folder."""
    manifest_path = out / MANIFEST
    if resume and manifest_path.is_file():
        from dualtwin.artifacts import read_json_object

        manifest = read_json_object(manifest_path, what="dataset manifest")
        differ = [k for k, v in settings.items() if manifest.get(k) != v]
        if differ:
            raise DualtwinError(f"{manifest_path}: cannot resume: {', '.join(differ)} differ from the "
                                "interrupted collection")
        shards = list(manifest.get("shards", []))
        for shard in check_manifest(manifest, manifest_path).shards:
            path = out / shard.file
            if not path.is_file() or sha256_file(path) != shard.sha256:
                raise DualtwinError(f"{path}: missing or modified since it was recorded; cannot resume")
        return shards
    if out.exists() and any(out.iterdir()) and not resume:
        raise DualtwinError(f"{out}: output folder is not empty; use resume to continue a collection, "
                            "or choose another folder")
    out.mkdir(parents=True, exist_ok=True)
    return []


def _write_manifest(out: Path, settings: dict[str, Any], shards: list[dict[str, Any]], episodes: int) -> None:
    finished = shards[-1]["episodes"][1] + 1 if shards else 0
    write_json(out / MANIFEST, {
        **settings, "episodes": episodes, "episodes_done": finished, "complete": finished >= episodes,
        "frames": int(sum(s["frames"] for s in shards)), "shards": shards,
        "layout": {"frames": "uint8 [N, H, W, 3] RGB", "state": "float32 [N, 4] (names in 'state')",
                   "time_s": "float64 [N] simulation time since reset", "episode": "int64 [N]",
                   "step": "int64 [N] control period index", "observation": "float32 [N, n_obs] env observation",
                   "action": "float32 [N, n_act] action applied after the frame",
                   "masks": f"uint8 [N, H, W, {len(LABEL_BODIES)}] coverage 0..255 of {list(LABEL_BODIES)}"},
        "versions": package_versions(),
    })


@dataclass
class Dataset:
    """A loaded dataset: every shard's rows concatenated, plus the manifest."""

    manifest: dict[str, Any]
    frames: np.ndarray
    state: np.ndarray
    time_s: np.ndarray
    episode: np.ndarray
    step: np.ndarray
    observation: np.ndarray
    action: np.ndarray
    masks: np.ndarray

    def __len__(self) -> int:
        return int(len(self.frames))

    @property
    def episodes(self) -> np.ndarray:
        return np.unique(self.episode)


class ShardRecord(BaseModel):
    """One finished shard as the manifest lists it (fields added by later versions are ignored)."""

    file: str = Field(min_length=1)
    episodes: tuple[_Count, _Count]
    frames: Annotated[int, Strict(), Field(ge=1)]
    sha256: str
    episode_ids: list[str] | None = None

    @model_validator(mode="after")
    def _ordered(self) -> ShardRecord:
        first, last = self.episodes
        if last < first:
            raise ValueError(f"episodes [{first}, {last}]: the last episode comes before the first")
        if self.episode_ids is not None and len(self.episode_ids) != last - first + 1:
            raise ValueError(f"{len(self.episode_ids)} episode ids for episodes {first}..{last}")
        return self


class ManifestFields(BaseModel):
    """The manifest fields readers compute with: a manifest is untrusted input (a shared dataset folder)."""

    env_id: str
    seed: _Count = 0
    resolution: tuple[Annotated[int, Strict(), Field(ge=1, le=4096)], Annotated[int, Strict(), Field(ge=1, le=4096)]]
    observation: list[str] = Field(default_factory=list)
    shards: list[ShardRecord] = Field(default_factory=list)


def check_manifest(manifest: dict[str, Any], path: Path) -> ManifestFields:
    """The manifest's fields that readers use, validated; every shard file confined to the dataset folder.

    Raises:
        DualtwinError: naming the manifest and the JSON path of the first bad field.
    """
    from pydantic import ValidationError

    from dualtwin.artifacts import confined_file
    from dualtwin.models import validation_message

    try:
        fields = ManifestFields.model_validate(manifest)
    except ValidationError as exc:
        raise DualtwinError(validation_message(path, exc)) from None
    for i, shard in enumerate(fields.shards):
        confined_file(path.parent, shard.file, f"{path}: $.shards[{i}].file")
    return fields


def read_manifest(directory: Path | str) -> dict[str, Any]:
    path = Path(directory) / MANIFEST
    if not path.is_file():
        raise DualtwinError(f"{directory}: not a perception dataset (no {MANIFEST})")
    from dualtwin.artifacts import read_json_object

    manifest: dict[str, Any] = read_json_object(path, what="dataset manifest")  # names file, line and column
    if manifest.get("format") != FORMAT or manifest.get("format_version") != FORMAT_VERSION:
        raise DualtwinError(f"{path}: unsupported dataset format {manifest.get('format')!r} "
                            f"v{manifest.get('format_version')} (this version reads {FORMAT} v{FORMAT_VERSION})")
    check_manifest(manifest, path)
    return manifest


#: What every shard holds: dtype and the shape after the row axis (a name is a size fixed per dataset: H and W
#: by the manifest's resolution, n_obs and n_act by the first shard).
_ARRAYS: dict[str, tuple[str, tuple[int | str, ...]]] = {
    "frames": ("uint8", ("H", "W", 3)), "state": ("float32", (len(STATE),)), "time_s": ("float64", ()),
    "episode": ("int64", ()), "step": ("int64", ()), "observation": ("float32", ("n_obs",)),
    "action": ("float32", ("n_act",)), "masks": ("uint8", ("H", "W", len(LABEL_BODIES))),
}


def _read_shard(path: Path, record: ShardRecord, sizes: dict[str, int]) -> dict[str, np.ndarray]:
    """A shard's arrays, checked against the layout and its manifest record before any computation sees them.

    ``sizes`` holds H and W (the manifest's resolution) and learns n_obs and n_act from the first shard, so
    that every shard concatenates. Rows must be whole episodes in order (step 0, 1, ... within each), as
    ``collect`` writes them: frame stacks are found by stepping back ``step`` rows.
    """
    import zipfile
    import zlib

    try:
        with np.load(path, allow_pickle=False) as data:
            missing = [k for k in KEYS if k not in data.files]
            if missing:
                raise DualtwinError(f"{path}: shard lacks the arrays {missing}")
            arrays = {k: data[k] for k in KEYS}
    except DualtwinError:
        raise
    except (OSError, EOFError, ValueError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        # np.load raises ValueError for object (pickled) arrays and for a damaged header; zipfile and zlib for a
        # truncated or corrupt archive.
        raise DualtwinError(f"{path}: not a readable dataset shard ({type(exc).__name__}: {exc})") from None
    rows = len(arrays["frames"]) if arrays["frames"].ndim else -1
    for key, (dtype, tail) in _ARRAYS.items():
        array = arrays[key]
        shape: list[int] = []
        for size in tail:
            if isinstance(size, str):
                size = sizes.setdefault(size, array.shape[len(shape) + 1] if array.ndim == len(tail) + 1 else -1)
            shape.append(size)
        if array.dtype != np.dtype(dtype) or list(array.shape) != [rows, *shape]:
            raise DualtwinError(f"{path}: {key!r} is {array.dtype} {list(array.shape)}, expected {dtype} "
                                f"{[rows, *shape]} ({rows} frames of {sizes['W']}x{sizes['H']})")
    if rows != record.frames:
        raise DualtwinError(f"{path}: {rows} frames, the manifest records {record.frames}")
    for key in ("state", "time_s", "observation", "action"):
        if not np.isfinite(arrays[key]).all():
            raise DualtwinError(f"{path}: {key!r} holds non-finite values")
    episode, step = arrays["episode"], arrays["step"]
    first, last = record.episodes
    starts = np.ones(rows, dtype=bool)
    starts[1:] = episode[1:] != episode[:-1]
    expected = np.arange(rows) - np.maximum.accumulate(np.where(starts, np.arange(rows), 0))
    if episode.min() < first or episode.max() > last or not np.array_equal(step, expected):
        raise DualtwinError(f"{path}: rows must be whole episodes {first}..{last} in order, each with steps 0, 1, "
                            "...; the episode and step arrays disagree")
    return arrays


def load_dataset(directory: Path | str, *, verify: bool = True) -> Dataset:
    """Load every finished shard (checking sha256 when ``verify``); never unpickles anything.

    Raises:
        DualtwinError: the manifest or a shard is malformed, a shard file is missing, modified, or not inside
            the dataset folder.
    """
    root = Path(directory)
    manifest = read_manifest(root)
    fields = check_manifest(manifest, root / MANIFEST)
    parts: dict[str, list[np.ndarray]] = {k: [] for k in KEYS}
    if not fields.shards:
        raise DualtwinError(f"{root}: dataset has no finished shard")
    width, height = fields.resolution
    sizes = {"H": height, "W": width}
    for shard in fields.shards:
        path = root / shard.file
        if not path.is_file():
            raise DualtwinError(f"{path}: shard listed in the manifest is missing")
        if verify and sha256_file(path) != shard.sha256:
            raise DualtwinError(f"{path}: sha256 differs from the manifest (modified or corrupt)")
        for key, array in _read_shard(path, shard, sizes).items():
            parts[key].append(array)
    return Dataset(manifest, **{k: np.concatenate(v) for k, v in parts.items()})
