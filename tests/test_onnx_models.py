"""``onnx_models.check_float_input``, the input check that the lockstep loader (sync) and the server's policy loader
(perception) share: one float32 ``[batch, n]`` input, or one DualtwinError naming the file and the inputs."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.onnx_models import check_float_input, open_session

onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
from onnx import TensorProto, helper  # noqa: E402


def _session(tmp_path: Path, inputs: list[tuple[str, int, Any]]) -> tuple[Any, Path]:
    """A session whose graph passes its first input through; the other inputs are declared and unused."""
    declared = [helper.make_tensor_value_info(name, kind, shape) for name, kind, shape in inputs]
    out = helper.make_tensor_value_info("out", inputs[0][1], inputs[0][2])
    graph = helper.make_graph([helper.make_node("Identity", [inputs[0][0]], ["out"])], "g", declared, [out])
    path = tmp_path / "m.onnx"
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=9), str(path))
    return open_session(path, "test"), path


def test_one_float_batch_by_n_input_is_accepted(tmp_path: Path) -> None:
    session, path = _session(tmp_path, [("obs", TensorProto.FLOAT, ["batch", 4])])
    check_float_input(session, path, "is refused")
    check_float_input(session, path, "is refused", width=4)


@pytest.mark.parametrize(("inputs", "width"), [
    ([("obs", TensorProto.DOUBLE, ["batch", 4])], None),  # another type
    ([("obs", TensorProto.FLOAT, [])], None),  # a scalar: no shape to index
    ([("obs", TensorProto.FLOAT, None)], None),  # rank-less
    ([("obs", TensorProto.FLOAT, ["batch", 2, 2])], None),  # another rank
    ([("obs", TensorProto.FLOAT, ["batch", 4]), ("extra", TensorProto.FLOAT, ["batch", 4])], None),  # two inputs
    ([("obs", TensorProto.FLOAT, ["batch", 3])], 4),  # another width than the contract's
])
def test_another_input_is_one_error_naming_file_and_inputs(tmp_path: Path, inputs: Any, width: int | None) -> None:
    session, path = _session(tmp_path, inputs)
    with pytest.raises(DualtwinError) as err:
        check_float_input(session, path, "is not what the caller feeds", width=width)
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ONNX input [('obs', ")
    assert message.endswith("is not what the caller feeds")
