"""An ONNX model from a folder is untrusted data that ONNX Runtime executes: a hostile graph (one that never ends,
allocates terabytes, takes another input or returns outputs of other shapes) is one DualtwinError naming the file,
never a hang, a traceback or ORT's own log records on stderr (found by fuzzing exported policies with graphs built
by the ``onnx`` helper API, run through ``OnnxPolicy`` (the server's loader) and ``dualtwin lockstep --policy``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualtwin.cli import main
from dualtwin.errors import DualtwinError
from dualtwin.perception.onnx_policy import POLICY_CONTRACT, POLICY_FILE, OnnxPolicy

onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
from onnx import TensorProto, helper, numpy_helper  # noqa: E402

OBS = helper.make_tensor_value_info("observation", TensorProto.FLOAT, ["batch", 4])


def _array(name: str, value: Any, dtype: Any = np.float32) -> Any:
    return numpy_helper.from_array(np.asarray(value, dtype=dtype), name)


def _policy(folder: Path, nodes: list[Any], inputs: list[Any], outputs: list[Any], inits: list[Any]) -> Path:
    """A policy folder with the continuous CartPole's contract (4 observations, one command) and this graph."""
    graph = helper.make_graph(nodes, "hostile", inputs, outputs, inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=9)
    folder.mkdir(parents=True)
    onnx.save(model, str(folder / POLICY_FILE))
    terms = [{"name": n, "source": "privileged"}
             for n in ("cart_position", "cart_velocity", "pole_angle", "pole_angular_velocity")]
    (folder / POLICY_CONTRACT).write_text(json.dumps({
        "env_id": "dualtwin/CartPole-MuJoCo-Continuous-v0", "env_kwargs": {}, "control_period_s": 0.02,
        "observation": terms, "action": {"type": "box", "names": ["cart_velocity"]}}))
    return folder


def _linear(observation: str = "observation") -> tuple[list[Any], list[Any], list[Any]]:
    """action [batch, 1] = observation @ w; cart_velocity [batch] = action[:, 0]."""
    nodes = [helper.make_node("MatMul", [observation, "w"], ["action"]),
             helper.make_node("Squeeze", ["action", "axis"], ["cart_velocity"])]
    outputs = [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["batch", 1]),
               helper.make_tensor_value_info("cart_velocity", TensorProto.FLOAT, ["batch"])]
    return nodes, outputs, [_array("w", [[0.1], [1.0], [0.5], [0.2]]), _array("axis", [1], np.int64)]


def endless_loop(folder: Path) -> Path:
    """A Loop whose condition stays true and has no trip count: ORT would run it forever."""
    any_shape = helper.make_tensor_value_info
    body = helper.make_graph(
        [helper.make_node("Identity", ["c_in"], ["c_out"]), helper.make_node("Identity", ["v_in"], ["v_out"])],
        "body", [any_shape("i", TensorProto.INT64, []), any_shape("c_in", TensorProto.BOOL, []),
                 any_shape("v_in", TensorProto.FLOAT, None)],
        [any_shape("c_out", TensorProto.BOOL, []), any_shape("v_out", TensorProto.FLOAT, None)])
    nodes, outputs, inits = _linear("looped")
    loop = helper.make_node("Loop", ["", "always", "observation"], ["looped"], body=body)
    return _policy(folder, [loop, *nodes], [OBS], outputs, [*inits, _array("always", True, np.bool_)])


def terabyte_constant(folder: Path) -> Path:
    """A ConstantOfShape of 10**12 floats, added to the observation: ORT fails while running."""
    nodes, outputs, inits = _linear("shifted")
    big = [helper.make_node("ConstantOfShape", ["shape"], ["big"], value=_array("one", [1.0])),
           helper.make_node("ReduceSum", ["big"], ["sum"], keepdims=0),
           helper.make_node("Add", ["observation", "sum"], ["shifted"])]
    return _policy(folder, [*big, *nodes], [OBS], outputs, [*inits, _array("shape", [10**6, 10**6], np.int64)])


def scalar_input(folder: Path) -> Path:
    nodes, outputs, inits = _linear("row")
    scalar = helper.make_tensor_value_info("observation", TensorProto.FLOAT, [])
    reshape = helper.make_node("Reshape", ["observation", "to_row"], ["row"])
    return _policy(folder, [reshape, *nodes], [scalar], outputs, [*inits, _array("to_row", [1, 4], np.int64)])


def double_input(folder: Path) -> Path:
    nodes, outputs, inits = _linear("cast")
    doubles = helper.make_tensor_value_info("observation", TensorProto.DOUBLE, ["batch", 4])
    cast = helper.make_node("Cast", ["observation"], ["cast"], to=TensorProto.FLOAT)
    return _policy(folder, [cast, *nodes], [doubles], outputs, inits)


def _with_command(folder: Path, node: Any, kind: int, shape: list[Any]) -> Path:
    nodes, outputs, inits = _linear()
    command = helper.make_tensor_value_info(node.output[0], kind, shape)
    return _policy(folder, [*nodes, node], [OBS], [outputs[0], command], [*inits, _array("reps", [1, 1000], np.int64)])


def text_command(folder: Path) -> Path:
    return _with_command(folder, helper.make_node("Cast", ["cart_velocity"], ["text"], to=TensorProto.STRING),
                         TensorProto.STRING, ["batch"])


def thousand_commands(folder: Path) -> Path:
    return _with_command(folder, helper.make_node("Tile", ["action", "reps"], ["wide"]), TensorProto.FLOAT,
                         ["batch", 1000])


def test_a_graph_that_never_ends_is_stopped(tmp_path: Path) -> None:
    policy = OnnxPolicy.load_exported(endless_loop(tmp_path / "p"))
    policy.run_limit_s = 0.5
    with pytest.raises(DualtwinError, match="ran longer than 0.5 s"):
        policy.run(np.zeros((1, 4)))


@pytest.mark.parametrize("make", [terabyte_constant, text_command, thousand_commands])
def test_a_graph_failing_or_answering_off_contract_is_one_error(tmp_path: Path, make: Any) -> None:
    policy = OnnxPolicy.load_exported(make(tmp_path / "p"))
    with pytest.raises(DualtwinError, match=POLICY_FILE):
        policy.run(np.zeros((1, 4)))


def test_a_scalar_input_is_refused_at_load(tmp_path: Path) -> None:
    with pytest.raises(DualtwinError, match="does not take the contract's 4 float observations"):
        OnnxPolicy.load_exported(scalar_input(tmp_path / "p"))


def test_no_external_data_is_read_from_outside_the_folder(tmp_path: Path) -> None:
    # ORT refuses it itself (since 1.2x); this pins that the refusal reaches the user as one error.
    folder = double_input(tmp_path / "p")
    model = onnx.load(str(folder / POLICY_FILE))
    (tmp_path / "secret.bin").write_bytes(np.zeros(4, np.float32).tobytes())
    weight = next(t for t in model.graph.initializer if t.name == "w")
    weight.ClearField("raw_data")
    weight.data_location = TensorProto.EXTERNAL
    entry = weight.external_data.add()
    entry.key, entry.value = "location", "../secret.bin"
    onnx.save(model, str(folder / POLICY_FILE))
    with pytest.raises(DualtwinError, match="not a valid ONNX policy model"):
        OnnxPolicy.load_exported(folder)


@pytest.mark.parametrize("make", [double_input, terabyte_constant, scalar_input])
def test_lockstep_says_one_line(tmp_path: Path, make: Any, capfd: pytest.CaptureFixture[str]) -> None:
    # capfd, not capsys: ORT's logger writes to file descriptor 2 from C++.
    folder = make(tmp_path / "p")
    capfd.readouterr()
    code = main(["lockstep", "--robot", "cartpole", "--policy", str(folder), "--episodes", "1",
                 "--out", str(tmp_path / "out")])
    err = capfd.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and POLICY_FILE in err, err
    assert not (tmp_path / "out").exists()


def _perception_part(path: Path, out: list[Any], nodes: list[Any], inputs: list[Any], inits: list[Any]) -> None:
    graph = helper.make_graph(nodes, "hostile", inputs, out, inits)
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=9), str(path))


def _rehash(folder: Path) -> None:
    """The contract records each file's sha256: a hostile folder records its own files' hashes."""
    import hashlib

    from dualtwin.perception.estimator import CONTRACT_FILE

    contract = json.loads((folder / CONTRACT_FILE).read_text())
    onnx_entry = contract["onnx"]
    for entry in (onnx_entry, *onnx_entry.get("parts", {}).values()):
        entry["sha256"] = hashlib.sha256((folder / entry["file"]).read_bytes()).hexdigest()
    (folder / CONTRACT_FILE).write_text(json.dumps(contract))


@pytest.fixture
def perception_model(tiny_model: Path, tmp_path: Path) -> Path:
    import shutil

    return Path(shutil.copytree(tiny_model, tmp_path / "model"))


def test_a_perception_model_with_a_scalar_output_is_refused_at_load(perception_model: Path) -> None:
    from dualtwin.perception.estimator import StateEstimator

    contract = json.loads((perception_model / "perception_contract.json").read_text())
    frames = helper.make_tensor_value_info("frames", TensorProto.UINT8, contract["onnx"]["inputs"][0]["shape"])
    _perception_part(perception_model / contract["onnx"]["file"],
                     [helper.make_tensor_value_info("state", TensorProto.FLOAT, [])],
                     [helper.make_node("Cast", ["frames"], ["f"], to=TensorProto.FLOAT),
                      helper.make_node("ReduceSum", ["f"], ["state"], keepdims=0)], [frames], [])
    _rehash(perception_model)
    with pytest.raises(DualtwinError, match="does not give the contract's 4 state quantities"):
        StateEstimator.load(perception_model)


def test_a_perception_head_answering_off_contract_is_one_line(perception_model: Path, tiny_dataset: Path,
                                                               capfd: pytest.CaptureFixture[str]) -> None:
    # The head part's output is 7 numbers per frame stack where the contract names 4: the filter broadcast failed.
    contract = json.loads((perception_model / "perception_contract.json").read_text())
    head = perception_model / contract["onnx"]["parts"]["head"]["file"]
    features = onnx.load(str(head)).graph.input[0]
    width = int(np.prod([d.dim_value for d in features.type.tensor_type.shape.dim[1:]]))
    _perception_part(head, [helper.make_tensor_value_info("state", TensorProto.FLOAT, ["batch", 4])],
                     [helper.make_node("Flatten", ["features"], ["flat"]), helper.make_node("MatMul", ["flat", "w"],
                                                                                            ["state"])],
                     [features], [_array("w", np.ones((width, 7)) * 0.01)])
    _rehash(perception_model)
    capfd.readouterr()
    code = main(["perception", "eval", "--model", str(perception_model), "--data", str(tiny_dataset)])
    err = capfd.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and head.name in err, err
