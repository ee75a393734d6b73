"""Fuzz the RobotServer from its own OpenAPI schema (schemathesis) over real HTTP on loopback.

Every operation gets schema-conforming and schema-violating requests (bounded, derandomised examples) against a
real uvicorn server: no answer is a 5xx, every status code, content type and JSON body conforms to the schema,
and data the schema forbids is rejected. Whether a conforming request is *accepted* is not checked: the schema
cannot say that a string must be a PNG of the camera's size, so most generated frames are rightly refused.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import httpx
import pytest

schemathesis = pytest.importorskip("schemathesis")

from hypothesis import HealthCheck, given, settings  # noqa: E402
from schemathesis import GenerationMode  # noqa: E402

from dualtwin.server.app import create_app  # noqa: E402
from tests.support.servers import RunningServer  # noqa: E402

KEY = "fuzz-key"
EXAMPLES = {GenerationMode.POSITIVE: 40, GenerationMode.NEGATIVE: 40}


@pytest.fixture(scope="module")
def server(policy_dir: Path, perception_dir: Path) -> Any:
    app = create_app(policy_dir, perception_dir, api_key=KEY, max_body_bytes=64 * 1024, max_frame_pixels=4096,
                     max_sessions=8, max_total_sessions=32)
    with RunningServer(app) as running:
        yield running


def test_the_schema_itself_needs_the_key_and_docs_are_off(server: Any) -> None:
    assert httpx.get(f"{server.url}/openapi.json").status_code == 401
    assert httpx.get(f"{server.url}/openapi.json", headers={"X-API-Key": "wrong"}).status_code == 401
    for page in ("/docs", "/redoc"):
        assert httpx.get(f"{server.url}{page}", headers={"X-API-Key": KEY}).status_code == 404
    schema = httpx.get(f"{server.url}/openapi.json", headers={"X-API-Key": KEY}).json()
    assert "ActRequest" in schema["components"]["schemas"] and "/v1/act" in schema["paths"]


@pytest.mark.parametrize("mode", list(EXAMPLES), ids=str)
def test_fuzz_every_operation_from_the_openapi_schema(server: Any, mode: GenerationMode) -> None:
    assert server.url.startswith("http://127.0.0.1:")  # loopback only
    headers = {"X-API-Key": KEY}
    raw = httpx.get(f"{server.url}/openapi.json", headers=headers).json()
    if mode == GenerationMode.NEGATIVE:
        # Violate the body, not the key header: a wrong key is one 401 (tested above), and with the header in
        # play most negative cases would stop there.
        raw["components"].pop("securitySchemes", None)
        for path in raw["paths"].values():
            for operation in path.values():
                operation.pop("security", None)
    schema = schemathesis.openapi.from_dict(raw)
    checks = schemathesis.checks
    excluded = [checks.positive_data_acceptance]
    operations = [result.ok() for result in schema.get_all_operations()]
    assert {op.path for op in operations} == {"/healthz", "/v1/info", "/v1/policy.onnx", "/v1/act"}
    calls: list[int] = []
    for operation in operations:
        if mode == GenerationMode.NEGATIVE and operation.path != "/v1/act":
            continue  # the GET operations take no input to violate

        @settings(max_examples=EXAMPLES[mode], deadline=None, derandomize=True, database=None,
                  suppress_health_check=list(HealthCheck))
        @given(case=operation.as_strategy(generation_mode=mode))
        def run(case: Any) -> None:
            response = case.call_and_validate(base_url=server.url, headers=headers, excluded_checks=excluded,
                                              timeout=30)
            calls.append(response.status_code)
            assert response.status_code < 500

        run()
    assert len(calls) >= EXAMPLES[mode] and all(code < 500 for code in calls)
    # The server is still healthy and serving after the fuzzing.
    assert httpx.get(f"{server.url}/healthz").json() == {"status": "ok"}


def _png(size: int) -> bytes:
    import io

    import numpy as np
    from PIL import Image

    buffer = io.BytesIO()
    pixels = np.random.default_rng(0).integers(0, 255, (size, size, 3), dtype=np.uint8)
    Image.fromarray(pixels).save(buffer, format="PNG")
    return buffer.getvalue()


def _bomb_header() -> bytes:
    """A PNG whose header claims 100000 x 100000 pixels (its data is 100 bytes): refused from the header."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", 100_000, 100_000, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\x00" * 100))


def test_frame_decoder_fuzz_mutated_pngs_and_other_formats(server: Any, policy_dir: Path) -> None:
    """Bytes that get past the JSON schema to the image decoder: mutated PNGs, other formats, bombs."""
    import base64
    import json

    from hypothesis import strategies as st

    from tests.support.servers import SIZE

    terms = json.loads((policy_dir / "policy_contract.json").read_text())["observation"]
    sensors = {t["name"]: 0.0 for t in terms if t["source"] == "onboard"}
    good = _png(SIZE)
    gif = b"GIF89a" + b"\x20\x00\x20\x00" + b"\x00" * 64
    bmp = b"BM" + b"\x00" * 60
    statuses: list[int] = []
    with httpx.Client(base_url=server.url, headers={"X-API-Key": KEY}, timeout=30) as client:

        def send(data: bytes) -> int:
            body = {"session": "decoder-fuzz", "sensors": sensors,
                    "frame": {"png_base64": base64.b64encode(data).decode()}}
            reply = client.post("/v1/act", json=body)
            statuses.append(reply.status_code)
            assert reply.status_code < 500, reply.text
            return reply.status_code

        assert send(good) == 200  # the control: the unmutated frame is served
        assert send(_bomb_header()) == 413
        for other in (gif, bmp, b"\x89PNG", b""):
            assert send(other) == 422  # Pillow is not asked to parse GIF/BMP headers at all

        @settings(max_examples=80, deadline=None, derandomize=True, database=None,
                  suppress_health_check=list(HealthCheck))
        @given(flips=st.lists(st.tuples(st.integers(0, len(good) - 1), st.integers(0, 255)), max_size=8),
               cut=st.one_of(st.just(len(good)), st.integers(1, len(good))))
        def mutated(flips: list[tuple[int, int]], cut: int) -> None:
            data = bytearray(good[:cut])
            for position, value in flips:
                if position < len(data):
                    data[position] = value
            send(bytes(data))

        mutated()
    assert set(statuses) <= {200, 413, 422} and statuses.count(422) > 40
