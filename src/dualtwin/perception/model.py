"""The perception model: a small CNN from a stack of the last k frames to the robot's state.

Input: the last ``k`` RGB frames of one camera, oldest first, one per control period (uint8, ``[batch, k, H, W,
3]``); before ``k`` frames exist the first frame is repeated (as at the start of every training episode).
Output: ``[cart_position, cart_velocity, pole_angle, pole_angular_velocity]`` in m, m/s, rad, rad/s.

Architecture (see :func:`_build`): each frame goes through a small fully convolutional pixel classifier (pole,
cart) trained with the rendered masks as dense labels; weighted moments of the predicted masks give each
frame's geometry (pole position, its slope in the image, its spread; cart position); an MLP over the k frames'
moments returns the state, velocities included (the frames are a known control period apart). At run time
:class:`dualtwin.perception.estimator.StateEstimator` can instead derive the velocities with an α-β filter.

Pixel scaling (``/255 - 0.5``) and output de-normalisation (``y * std + mean`` of the training labels) are
inside the graph, so ``perception.onnx`` takes raw frames and returns physical units. Training is PyTorch on
CPU with few threads; the split is by episode (whole episodes held out), seeded. The loss is a weighted
smooth-L1 on the normalised state plus the masks' binary cross-entropy.

Folder written by :func:`train_perception`::

    perception.onnx            the model (opset 17)
    perception_frame.onnx      the same model in two parts, for streams: one frame -> its mask moments ...
    perception_head.onnx       ... and the k frames' moments -> the state (each frame is segmented once)
    perception_contract.json   input shape/dtype/normalisation, outputs and units, camera, frame period, metrics
    training.json              config, split (held-out episodes), per-epoch losses, dataset fingerprint
    weights.npz                the trained weights as plain arrays (fine-tuning, parity checks)
    timing.json                wall-clock seconds (total, per epoch): the one file that differs between two
                               runs with the same seed and inputs, so training.json holds no time
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dualtwin.artifacts import atomic_open, package_versions, sha256_file, write_json
from dualtwin.errors import DualtwinError
from dualtwin.perception.dataset import STATE_NAMES, STATE_UNITS, Dataset, episode_identities, load_dataset
from dualtwin.reporting import Progress, ProgressCallback

if TYPE_CHECKING:
    import torch

OPSET = 17
CONTRACT_VERSION = 1
MODEL_FILE = "perception.onnx"
CONTRACT_FILE = "perception_contract.json"
WEIGHTS_FILE = "weights.npz"
DEFAULT_STACK = 3
#: Loss weights per state quantity (normalised units): the pole angle is what balancing needs most.
LOSS_WEIGHTS = (1.0, 1.0, 2.0, 1.0)
#: Weight of the mask (segmentation) loss, and of the pole and cart pixels within it.
MASK_LOSS_WEIGHT = 1.0
MASK_POS_WEIGHT = (2.0, 1.0)


def stack_indices(dataset: Dataset, rows: np.ndarray, k: int) -> np.ndarray:
    """Row indices [len(rows), k] of each row's frame stack, oldest first, repeating the episode's first frame."""
    offsets = np.arange(k - 1, -1, -1)
    back = np.minimum(offsets[None, :], dataset.step[rows][:, None])
    return rows[:, None] - back


def split_episodes(episodes: np.ndarray, holdout: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(train, held-out) episode ids: a seeded shuffle, at least one episode on each side."""
    if len(episodes) < 2:
        raise DualtwinError(f"the dataset has {len(episodes)} episode(s); the split by episode needs at least 2")
    order = np.random.default_rng(seed).permutation(episodes)
    n_test = min(max(1, int(round(holdout * len(order)))), len(order) - 1)
    return np.sort(order[n_test:]), np.sort(order[:n_test])


#: Geometric features per frame: pole (mass, x, y, slope, y spread) and cart (mass, x, y).
N_FEATURES = 8
#: Mask pixels below this probability count as background in the moments (keeps far pixels from biasing them).
MASK_FLOOR = 0.1


def _build(k: int, height: int, width: int, mean: np.ndarray, std: np.ndarray) -> Any:
    """The perception network: per-frame segmentation, mask moments, and a head over the k frames' moments.

    Why this shape: the pole is about one pixel wide at 64x64 and a tilt of 0.02 rad moves its tip by about
    half a pixel. A generic CNN regressor learns the cart (a large blob) quickly but the pole only after very
    long training. Supervising a pixel classifier with the rendered masks (dense labels, free in simulation)
    and reading positions and the pole's slope off the predicted masks as weighted moments keeps the
    anti-aliasing's sub-pixel information and trains in minutes on a CPU.
    """
    import torch
    from torch import nn

    class PerceptionNet(nn.Module):
        mean: torch.Tensor
        std: torch.Tensor
        grid_x: torch.Tensor
        grid_y: torch.Tensor

        def __init__(self) -> None:
            super().__init__()
            # A pixel classifier with a 5x5 context: pole, cart (logits), at full resolution.
            self.segment = nn.Sequential(nn.Conv2d(3, 12, 3, padding=1), nn.ReLU(), nn.Conv2d(12, 12, 3, padding=1),
                                         nn.ReLU(), nn.Conv2d(12, 2, 1))
            self.head = nn.Sequential(nn.Linear(k * N_FEATURES, 128), nn.ReLU(), nn.Linear(128, 128), nn.ReLU(),
                                      nn.Linear(128, len(STATE_NAMES)))
            ys = torch.linspace(-1.0, 1.0, height).reshape(1, height, 1).expand(1, height, width)
            xs = torch.linspace(-1.0, 1.0, width).reshape(1, 1, width).expand(1, height, width)
            self.register_buffer("grid_x", xs.contiguous())
            self.register_buffer("grid_y", ys.contiguous())
            self.register_buffer("mean", torch.tensor(mean, dtype=torch.float32))
            self.register_buffer("std", torch.tensor(std, dtype=torch.float32))

        def masks(self, frames: torch.Tensor) -> torch.Tensor:
            """Frames [n, H, W, 3] (uint8 or float 0..255) -> mask logits [n, 2, H, W]."""
            x = frames.to(torch.float32) * (1.0 / 255.0) - 0.5
            return self.segment(x.permute(0, 3, 1, 2))

        def features(self, logits: torch.Tensor) -> torch.Tensor:
            """Mask logits [n, 2, H, W] -> moments [n, N_FEATURES]."""
            p = torch.sigmoid(logits)
            p = p * (p > MASK_FLOOR).to(p.dtype)
            mass = p.sum(dim=(2, 3)) + 1e-3
            cx = (p * self.grid_x).sum(dim=(2, 3)) / mass
            cy = (p * self.grid_y).sum(dim=(2, 3)) / mass
            pole = p[:, 0]
            dx = self.grid_x - cx[:, 0, None, None]
            dy = self.grid_y - cy[:, 0, None, None]
            vyy = (pole * dy * dy).sum(dim=(1, 2)) / mass[:, 0]
            vxy = (pole * dx * dy).sum(dim=(1, 2)) / mass[:, 0]
            slope = vxy / (vyy + 1e-3)  # x change per y change along the pole: its tilt in the image
            scale = 100.0 / (height * width)
            return torch.stack([mass[:, 0] * scale, cx[:, 0], cy[:, 0], slope, vyy * 10.0, mass[:, 1] * scale,
                                cx[:, 1], cy[:, 1]], dim=1)

        def head_from(self, features: torch.Tensor) -> torch.Tensor:
            """Features [B, k, N_FEATURES] -> normalised state [B, 4]."""
            return self.head(features.reshape(features.shape[0], k * N_FEATURES))

        def forward(self, frames: torch.Tensor) -> torch.Tensor:
            """Frames uint8 [B, k, H, W, 3] -> state [B, 4] in physical units."""
            b = frames.shape[0]
            features = self.features(self.masks(frames.reshape(b * k, height, width, 3)))
            return self.head_from(features.reshape(b, k, N_FEATURES)) * self.std + self.mean

    return PerceptionNet()


def _augment(x: torch.Tensor, gen: torch.Generator, colour: float = 0.0) -> torch.Tensor:
    """Photometric jitter per frame: gain, offset, pixel noise (the masks do not change); with ``colour`` > 0
    also a gain per colour channel, exp(U(-colour, colour)), which shifts hues (another renderer's materials)."""
    import torch

    n = x.shape[0]
    gain = 0.8 + 0.4 * torch.rand(n, 1, 1, 1, generator=gen)
    if colour > 0:
        gain = gain * torch.exp((torch.rand(n, 1, 1, 3, generator=gen) * 2.0 - 1.0) * colour)
    offset = (torch.rand(n, 1, 1, 1, generator=gen) - 0.5) * 30.0
    noise = torch.randn(x.shape, generator=gen) * 3.0
    return (x * gain + offset + noise).clamp(0.0, 255.0)


def _windows(rows: np.ndarray, episode: np.ndarray, length: int, rng: np.random.Generator) -> list[np.ndarray]:
    """The rows cut into runs of consecutive frames of one episode, shuffled. A batch made of a few runs shares
    most frames between its stacks, so each frame is segmented once per batch (about k times less work)."""
    runs: list[np.ndarray] = []
    for ep in np.unique(episode[rows]):
        ep_rows = rows[episode[rows] == ep]
        offset = int(rng.integers(length))  # a random phase, so the runs differ from epoch to epoch
        cuts = list(range(offset, len(ep_rows), length))
        runs.extend(ep_rows[a:b] for a, b in zip([0, *cuts], [*cuts, len(ep_rows)], strict=True) if b > a)
    return [runs[i] for i in rng.permutation(len(runs))]


def train_perception(dataset_dir: Path | str, out_dir: Path | str, *, epochs: int = 15, seed: int = 0,
                     stack: int = DEFAULT_STACK, batch_size: int = 64, learning_rate: float = 2e-3,
                     holdout: float = 0.2, threads: int = 2, max_seconds: float | None = None,
                     progress: ProgressCallback | None = None, init_from: Path | str | None = None,
                     colour_jitter: float = 0.0) -> Path:
    """Train the CNN on a dataset folder, export ``perception.onnx`` + contract into ``out_dir``; returns out_dir.

    Args:
        dataset_dir: written by :func:`dualtwin.perception.collect`.
        out_dir: model folder (created; files in it are replaced atomically).
        epochs: passes over the training episodes' frames.
        seed: seeds the split, the initialisation, the batches and the augmentation.
        stack: frames per input (k); 2 or 3 give velocities.
        batch_size, learning_rate: Adam settings (one-cycle learning-rate schedule peaking at learning_rate).
        holdout: fraction of episodes held out for validation and :func:`evaluate_perception`.
        threads: ``torch.set_num_threads`` (keep small on shared machines).
        max_seconds: stop early after this much training time (the best epoch so far is exported).
        init_from: a model folder to continue training from (its ``weights.npz`` and label normalisation; same
            stack and resolution). The episodes it trained on count as trained on by the new model too, and
            none of them may be in this split's held-out episodes (that would score training data).
        colour_jitter: per-channel gain augmentation exp(U(-c, c)); 0 = off. Measured: a model trained on
            Webots-twin frames without it read MuJoCo-twin frames (a brighter orange pole) 5x worse.
        progress: Called after every epoch (stage ``perception train``) with the losses and held-out MAE.

    The model's contract records the identities of the episodes it trained on
    (:func:`dualtwin.perception.dataset.episode_identity`), so that evaluation can leave them out of any dataset.
    """
    import torch

    if epochs < 1 or stack < 1 or batch_size < 1:
        raise DualtwinError("epochs, stack and batch_size must be >= 1")
    if not 0.0 <= colour_jitter <= 2.0:
        raise DualtwinError(f"colour_jitter must be in [0, 2], got {colour_jitter}")
    torch.set_num_threads(max(1, int(threads)))
    torch.manual_seed(seed)
    data = load_dataset(dataset_dir)
    train_eps, test_eps = split_episodes(data.episodes, holdout, seed)
    identities = episode_identities(data.manifest)
    missing = sorted(set(int(e) for e in data.episodes) - set(identities))
    if missing:
        raise DualtwinError(f"{dataset_dir}: episodes {missing[:5]} have no identity in the manifest")
    counter = Progress(progress, "perception train", epochs)
    train_rows = np.flatnonzero(np.isin(data.episode, train_eps))
    test_rows = np.flatnonzero(np.isin(data.episode, test_eps))
    labels = data.state.astype(np.float32)
    mean = labels[train_rows].mean(axis=0)
    std = np.maximum(labels[train_rows].std(axis=0), 1e-3)
    _, height, width, _ = data.frames.shape
    inherited: set[str] = set()
    initial: dict[str, Any] | None = None
    if init_from is not None:
        initial, inherited = _initial_weights(Path(init_from), stack, height, width)
        leaked = sorted(int(e) for e in test_eps if identities[int(e)] in inherited)
        if leaked:
            raise DualtwinError(f"{init_from}: the initial model trained on episodes {leaked[:5]} that this split "
                                "holds out; use the same dataset and seed, or another split")
        # The head's outputs are in the initial model's normalised units: keep them.
        mean, std = initial["mean"].numpy(), initial["std"].numpy()
    net = _build(stack, height, width, mean, std)
    if initial is not None:
        net.load_state_dict(initial)
    frames = torch.from_numpy(data.frames)
    masks = torch.from_numpy(data.masks)
    target = torch.from_numpy((labels - mean) / std)
    weights = torch.tensor(LOSS_WEIGHTS, dtype=torch.float32)
    # The pole covers ~0.7 % of the pixels and the cart ~2 %: weigh the pole's up a little (more would bias
    # the predicted masks wider, and the moments with them).
    pos_weight = torch.tensor(MASK_POS_WEIGHT, dtype=torch.float32).reshape(1, 2, 1, 1)
    optimizer = torch.optim.Adam(net.parameters(), lr=learning_rate)
    steps_per_epoch = max(1, -(-len(train_rows) // batch_size))
    scheduler = torch.optim.lr_scheduler.OneCycleLR(optimizer, max_lr=learning_rate,
                                                    total_steps=epochs * (steps_per_epoch + 8), pct_start=0.15)
    gen = torch.Generator().manual_seed(seed)
    rng = np.random.default_rng(seed)
    history: list[dict[str, float]] = []
    epoch_seconds: list[float] = []  # wall clock at the end of each epoch: timing.json, not training.json
    best: tuple[float, dict[str, Any]] | None = None
    start = time.perf_counter()
    window = max(stack + 5, 8)
    for epoch in range(epochs):
        net.train()
        runs = _windows(train_rows, data.episode, window, rng)
        total, seen, batch_rows = 0.0, 0, []
        for i, run in enumerate(runs):
            batch_rows.append(run)
            if sum(len(r) for r in batch_rows) < batch_size and i < len(runs) - 1:
                continue
            rows = np.concatenate(batch_rows)
            batch_rows = []
            stacks = stack_indices(data, rows, stack)
            unique, inverse = np.unique(stacks, return_inverse=True)
            index = torch.from_numpy(unique)
            logits = net.masks(_augment(frames[index].float(), gen, colour_jitter))
            features = net.features(logits)[torch.from_numpy(inverse.reshape(-1))]
            predicted = net.head_from(features.reshape(len(rows), stack, N_FEATURES))
            state_loss = (torch.nn.functional.smooth_l1_loss(predicted, target[rows], reduction="none", beta=0.5)
                          * weights).mean()
            truth = masks[index].permute(0, 3, 1, 2).float() / 255.0
            mask_loss = torch.nn.functional.binary_cross_entropy_with_logits(logits, truth, pos_weight=pos_weight)
            loss = state_loss + MASK_LOSS_WEIGHT * mask_loss
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            if scheduler.last_epoch + 1 < scheduler.total_steps:
                scheduler.step()
            total += float(state_loss.detach()) * len(rows)
            seen += len(rows)
        val = _predict(net, data, test_rows, stack)
        val_loss = float(np.mean(np.abs((val - labels[test_rows]) / std) * np.asarray(LOSS_WEIGHTS)))
        mae = np.abs(val - labels[test_rows]).mean(axis=0)
        history.append({"epoch": epoch + 1, "train_loss": total / max(seen, 1), "val_loss": val_loss,
                        **{f"val_mae_{n}": float(v) for n, v in zip(STATE_NAMES, mae, strict=True)}})
        epoch_seconds.append(round(time.perf_counter() - start, 1))
        counter.advance(message=f"loss {total / max(seen, 1):.4f}, held-out loss {val_loss:.4f}; held-out MAE pole "
                                f"{mae[2]:.4f} rad, {mae[3]:.3f} rad/s; cart {mae[0]:.4f} m, {mae[1]:.3f} m/s")
        if best is None or val_loss < best[0]:
            best = (val_loss, {k: v.detach().clone() for k, v in net.state_dict().items()})
        if max_seconds is not None and time.perf_counter() - start > max_seconds:
            break
    assert best is not None
    net.load_state_dict(best[1])
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = _export(net, out, stack, height, width)
    parts = _export_parts(net, out, stack, height, width)
    # Weights as plain arrays (no pickle) for fine-tuning and parity checks: load_weights() rebuilds the net.
    with atomic_open(out / WEIGHTS_FILE, "wb") as handle:
        np.savez(handle, **{k: v.detach().numpy() for k, v in net.state_dict().items()})
    training = {
        "dataset": str(Path(dataset_dir).resolve()), "dataset_fingerprint": fingerprint(data.manifest),
        "seed": seed, "epochs": epochs, "epochs_run": len(history), "stack": stack, "batch_size": batch_size,
        "learning_rate": learning_rate, "holdout": holdout, "threads": threads, "loss_weights": list(LOSS_WEIGHTS),
        "train_episodes": [int(e) for e in train_eps], "heldout_episodes": [int(e) for e in test_eps],
        "train_episode_ids": [identities[int(e)] for e in train_eps],
        "heldout_episode_ids": [identities[int(e)] for e in test_eps],
        "train_frames": int(len(train_rows)), "heldout_frames": int(len(test_rows)), "history": history,
        "colour_jitter": colour_jitter,
        "init_from": None if init_from is None else {"path": str(Path(init_from).resolve()),
                                                     "weights_sha256": sha256_file(Path(init_from) / WEIGHTS_FILE)},
    }
    write_json(out / "training.json", training)
    write_json(out / "timing.json", {"seconds": round(time.perf_counter() - start, 1), "epoch_seconds": epoch_seconds})
    contract = _contract(path, data, stack, height, width, mean, std, history[-1])
    # What the model has seen, by episode identity: evaluation excludes these from any dataset.
    contract["trained_on"]["episodes"] = len(train_eps)
    contract["trained_on"]["episode_ids"] = sorted({identities[int(e)] for e in train_eps} | inherited)
    contract["onnx"]["parts"] = parts
    write_json(out / CONTRACT_FILE, contract)
    return out


def _initial_weights(folder: Path, stack: int, height: int, width: int) -> tuple[dict[str, Any], set[str]]:
    """A model folder's weights (as tensors, no pickle) and the episode identities it trained on."""
    from dualtwin.artifacts import read_json_object
    from dualtwin.perception.estimator import check_contract

    path = folder / CONTRACT_FILE
    contract = read_json_object(path, ("onnx",), what="perception contract")
    shape = check_contract(contract, path).onnx.inputs[0].shape
    if list(shape[1:4]) != [stack, height, width]:
        raise DualtwinError(f"{folder}: the initial model takes {shape[1]} frames of {shape[3]}x{shape[2]}, "
                            f"this training {stack} of {width}x{height}")
    weights = read_weights(folder / WEIGHTS_FILE, _build(stack, height, width, np.zeros(len(STATE_NAMES)),
                                                         np.ones(len(STATE_NAMES))))
    return weights, trained_episode_ids(folder, contract)


def read_weights(path: Path, net: Any) -> dict[str, Any]:
    """``weights.npz`` as tensors for ``net``: exactly its parameter names and shapes, finite floats, no pickle.

    A model folder is untrusted input: checked here, a damaged or foreign file is one error naming it instead of
    torch's multi-line ``load_state_dict`` failure (or a broadcasting error in the first training step).
    """
    import zipfile
    import zlib

    import torch

    if not path.is_file():
        raise DualtwinError(f"{path}: not found (the model needs its weights)")
    try:
        with np.load(path, allow_pickle=False) as arrays:
            loaded = {k: np.array(arrays[k]) for k in arrays.files}
    except (OSError, EOFError, ValueError, zipfile.BadZipFile, zlib.error) as exc:
        # ValueError: an object (pickled) array or a damaged header; BadZipFile/zlib: a truncated archive.
        raise DualtwinError(f"{path}: not a readable weights file ({type(exc).__name__}: {exc})") from None
    expected = {k: tuple(v.shape) for k, v in net.state_dict().items()}
    if set(loaded) != set(expected):
        raise DualtwinError(f"{path}: weights for another network (missing {sorted(set(expected) - set(loaded))[:5]}, "
                            f"unexpected {sorted(set(loaded) - set(expected))[:5]})")
    for name, array in loaded.items():
        if array.dtype.kind != "f" or array.shape != expected[name] or not np.isfinite(array).all():
            raise DualtwinError(f"{path}: {name!r} is {array.dtype} {list(array.shape)}, expected finite floats of "
                                f"shape {list(expected[name])}")
    if not (loaded["std"] > 0).all():
        raise DualtwinError(f"{path}: 'std' must be positive")
    return {k: torch.from_numpy(v.astype(np.float32)) for k, v in loaded.items()}


def load_weights(model_dir: Path | str) -> Any:
    """The trained PyTorch module of a model folder (from ``weights.npz`` and the contract; no pickle)."""
    folder = Path(model_dir)
    from dualtwin.artifacts import read_json_object
    from dualtwin.perception.estimator import check_contract

    path = folder / CONTRACT_FILE
    checked = check_contract(read_json_object(path, ("onnx", "normalization"), what="perception contract"), path)
    _, stack, height, width, _ = checked.onnx.inputs[0].shape
    norm = checked.normalization
    net = _build(int(stack), int(height), int(width), np.asarray(norm.mean), np.asarray(norm.std))
    net.load_state_dict(read_weights(folder / WEIGHTS_FILE, net))
    return net.eval()


def trained_episode_ids(model_dir: Path, contract: dict[str, Any]) -> set[str]:
    """The identities of the episodes a model trained on, from its contract (else its ``training.json``)."""
    import json

    ids = (contract.get("trained_on") or {}).get("episode_ids")
    if ids is None:
        path = Path(model_dir) / "training.json"
        try:
            ids = json.loads(path.read_text(encoding="utf-8")).get("train_episode_ids") if path.is_file() else None
        except (OSError, ValueError, AttributeError):
            ids = None
    if not isinstance(ids, list):
        raise DualtwinError(f"{model_dir}: the model does not record which episodes it trained on, so no dataset "
                            "can be shown to be held out; retrain it with this version")
    return {str(i) for i in ids}


def fingerprint(manifest: dict[str, Any]) -> str:
    """Identity of a dataset: its shards' hashes (the same data collected twice has the same fingerprint)."""
    import hashlib

    digest = hashlib.sha256()
    for shard in manifest.get("shards", []):
        digest.update(str(shard["sha256"]).encode())
    return digest.hexdigest()


def _predict(net: Any, data: Dataset, rows: np.ndarray, stack: int, batch: int = 256) -> np.ndarray:
    import torch

    net.eval()
    out = []
    with torch.no_grad():
        for i in range(0, len(rows), batch):
            idx = stack_indices(data, rows[i:i + batch], stack)
            out.append(net(torch.from_numpy(data.frames[idx])).numpy())
    return np.concatenate(out) if out else np.zeros((0, len(STATE_NAMES)), dtype=np.float32)


def _export(net: Any, out: Path, stack: int, height: int, width: int) -> Path:
    import torch

    net.eval()
    example = torch.zeros((1, stack, height, width, 3), dtype=torch.uint8)
    path = out / MODEL_FILE
    tmp = out / f".{MODEL_FILE}.tmp"
    # The TorchScript exporter (dynamo=False) needs no onnxscript; torch >= 2.9 marks it deprecated.
    with torch.no_grad(), warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=DeprecationWarning)
        warnings.filterwarnings("ignore", category=UserWarning)
        torch.onnx.export(net, (example,), str(tmp), input_names=["frames"], output_names=["state"],
                          opset_version=OPSET, dynamo=False,
                          dynamic_axes={"frames": {0: "batch"}, "state": {0: "batch"}})
    tmp.replace(path)
    return path


FRAME_PART_FILE = "perception_frame.onnx"
HEAD_PART_FILE = "perception_head.onnx"


def _export_parts(net: Any, out: Path, stack: int, height: int, width: int) -> dict[str, Any]:
    """The model split at the per-frame moments. A stream (a robot, a server session) then segments each new
    frame once and keeps the moments of the last k, instead of segmenting all k frames every period."""
    import torch

    class Part(torch.nn.Module):
        def __init__(self, head: bool) -> None:
            super().__init__()
            self.net, self.is_head = net, head  # a submodule: its weights export as initializers

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            if self.is_head:
                return self.net.head_from(x) * self.net.std + self.net.mean  # type: ignore[no-any-return]
            return self.net.features(self.net.masks(x))  # type: ignore[no-any-return]

    parts: dict[str, Any] = {}
    for key, module, example, names, axes in (
            ("frame", Part(False), torch.zeros((1, height, width, 3), dtype=torch.uint8), ("frames", "features"),
             {"frames": {0: "n"}, "features": {0: "n"}}),
            ("head", Part(True), torch.zeros((1, stack, N_FEATURES)), ("features", "state"),
             {"features": {0: "batch"}, "state": {0: "batch"}})):
        file = FRAME_PART_FILE if key == "frame" else HEAD_PART_FILE
        tmp = out / f".{file}.tmp"
        with torch.no_grad(), warnings.catch_warnings():
            warnings.filterwarnings("ignore", category=DeprecationWarning)
            warnings.filterwarnings("ignore", category=UserWarning)
            torch.onnx.export(module.eval(), (example,), str(tmp), input_names=[names[0]], output_names=[names[1]],
                              opset_version=OPSET, dynamo=False, dynamic_axes=axes)
        tmp.replace(out / file)
        parts[key] = {"file": file, "sha256": sha256_file(out / file),
                      "input": f"{names[0]} {list(example.shape[1:])} {str(example.dtype).removeprefix('torch.')}",
                      "output": f"{names[1]} [{N_FEATURES if key == 'frame' else len(STATE_NAMES)}]"}
    return parts


def _contract(path: Path, data: Dataset, stack: int, height: int, width: int, mean: np.ndarray, std: np.ndarray,
              last: dict[str, float]) -> dict[str, Any]:
    m = data.manifest
    return {
        "contract_version": CONTRACT_VERSION,
        "kind": "dualtwin-perception",
        "onnx": {
            "file": path.name, "sha256": sha256_file(path), "opset": OPSET,
            "inputs": [{"name": "frames", "dtype": "uint8", "shape": ["batch", stack, height, width, 3],
                        "meaning": "the last k RGB frames, oldest first, one per control period; before k frames "
                                   "exist, repeat the first"}],
            "outputs": [{"name": "state", "dtype": "float32", "shape": ["batch", len(STATE_NAMES)],
                         "meaning": "estimated state in the units below"}],
        },
        "normalization": {"input": "x = frames / 255 - 0.5 (in the graph)",
                          "output": "state = y * std + mean (in the graph)",
                          "mean": [float(v) for v in mean], "std": [float(v) for v in std]},
        "state": [{"index": i, "name": n, "unit": u} for i, (n, u) in enumerate(zip(STATE_NAMES, STATE_UNITS,
                                                                                      strict=True))],
        "frame_stack": stack,
        "frame_period_s": float(m.get("control_period_s", 0.0)),
        "camera": m.get("camera"),
        "resolution": [width, height],
        "trained_on": {"env_id": m.get("env_id"), "twin": m.get("twin"), "robot": m.get("robot"),
                       "controller": m.get("controller"), "randomization": m.get("randomization", {}).get("enabled"),
                       "frames": len(data)},
        "velocity": {"default": "kalman",
                     "options": {"kalman": "Kalman filter on the CNN's newest-frame positions (see StateEstimator)",
                                 "frame-stack": "the CNN's velocity outputs (motion across the k frames)"}},
        "validation": {k: v for k, v in last.items() if k.startswith("val_mae_")},
        "versions": package_versions(),
    }


def evaluate_perception(model_dir: Path | str, dataset_dir: Path | str, *, velocity: str = "kalman"
                        ) -> dict[str, Any]:
    """MAE per state quantity of the exported model (ONNX Runtime) on held-out episodes of a dataset.

    Held out means: not trained on, by episode identity (:func:`dualtwin.perception.dataset.episode_identity`).
    Every episode of the dataset whose identity the model's contract lists as trained on is left out, whatever
    dataset it arrives in (the training set, a subset of it, a resumed extension, a copy); the report says how
    many were. A dataset with nothing left is an error, not a score. Also reports a constant predictor (the
    training mean) as the baseline to beat, and the per-episode Kalman filter (velocities from positions).

    Raises:
        DualtwinError: The model does not record its training episodes, or no held-out episode remains.
    """
    from dualtwin.perception.estimator import StateEstimator

    model = Path(model_dir)
    estimator = StateEstimator.load(model)
    data = load_dataset(dataset_dir)
    trained = trained_episode_ids(model, estimator.contract)
    identities = episode_identities(data.manifest)
    excluded = sorted(e for e in (int(v) for v in data.episodes) if identities.get(e) in trained)
    episodes = np.asarray([int(e) for e in data.episodes if int(e) not in excluded], dtype=np.int64)
    if not len(episodes):
        raise DualtwinError(f"{dataset_dir}: all {len(excluded)} episode(s) were used to train {model}; "
                            "nothing is held out (collect another seed to evaluate)")
    rows = np.flatnonzero(np.isin(data.episode, episodes))
    if not len(rows):
        raise DualtwinError(f"{dataset_dir}: no held-out frames to evaluate on")
    res = data.frames.shape[2], data.frames.shape[1]
    if list(res) != list(estimator.resolution):
        raise DualtwinError(f"{dataset_dir}: frames are {res[0]}x{res[1]}, the model takes "
                            f"{estimator.resolution[0]}x{estimator.resolution[1]}")
    raw = estimator.predict_stacks(data.frames[stack_indices(data, rows, estimator.stack)])
    single = estimator.predict_single(data.frames[rows])
    filtered = np.zeros_like(raw)
    # The filter runs through each episode in time order, as it would on the robot.
    for episode in episodes:
        sel = np.flatnonzero(data.episode[rows] == episode)
        sel = sel[np.argsort(data.step[rows][sel])]
        session = estimator.session(velocity="kalman")
        for j in sel:
            filtered[j] = session.filter(single[j])  # what a kalman session computes for this frame
    truth = data.state[rows]
    mean = np.asarray(estimator.contract["normalization"]["mean"], dtype=np.float32)
    chosen = raw if velocity == "frame-stack" else filtered

    def table(pred: np.ndarray) -> dict[str, float]:
        return {n: float(v) for n, v in zip(STATE_NAMES, np.abs(pred - truth).mean(axis=0), strict=True)}

    return {
        "model": str(model), "dataset": str(dataset_dir), "heldout_episodes": [int(e) for e in episodes],
        "excluded_training_episodes": len(excluded), "excluded_episodes": excluded,
        "frames": int(len(rows)), "velocity": velocity,
        "mae": table(chosen), "mae_frame_stack": table(raw), "mae_kalman": table(filtered),
        "mae_constant": table(np.broadcast_to(mean, truth.shape)),
        "units": dict(zip(STATE_NAMES, STATE_UNITS, strict=True)),
    }
