"""Display: the drawing API on a headless RGBA buffer, and imageSave writing a real PNG."""

from __future__ import annotations

import itertools
import os
import struct
import subprocess
import sys
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Display, Supervisor
from dualtwin.webots.physics import Simulation

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture()
def display() -> Display:
    text = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { supervisor TRUE children [ Display { name "screen" width 16 height 8 } ] }
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    dev = sup.getDevice("screen")
    assert isinstance(dev, Display)
    return dev


def _read_png(path: Path) -> np.ndarray:
    """Decode an 8-bit RGBA, non-interlaced PNG with filter 0 rows (an independent reader)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, size = 8, b"", (0, 0)
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF
        if kind == b"IHDR":
            w, h, depth, colour = struct.unpack(">IIBB", body[:10])
            assert (depth, colour) == (8, 6)
            size = (h, w)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    h, w = size
    rows = [raw[y * (4 * w + 1) : (y + 1) * (4 * w + 1)] for y in range(h)]
    assert all(r[0] == 0 for r in rows)
    return np.frombuffer(b"".join(r[1:] for r in rows), dtype=np.uint8).reshape(h, w, 4)


def test_drawing_primitives(display: Display) -> None:
    assert (display.getWidth(), display.getHeight()) == (16, 8)
    display.setColor(0xFF0000)
    display.drawPixel(0, 0)
    display.setColor(0x00FF00)
    display.drawLine(0, 7, 7, 0)  # a diagonal
    display.setColor(0x0000FF)
    display.fillRectangle(10, 2, 3, 2)
    px = display.pixels
    assert px[0, 0].tolist() == [255, 0, 0, 255]
    assert all(px[7 - i, i].tolist() == [0, 255, 0, 255] for i in range(8))
    assert (px[2:4, 10:13] == [0, 0, 255, 255]).all() and px[4, 10, 3] == 0 and px[2, 13, 3] == 0
    display.setColor(0xFFFFFF)
    display.drawRectangle(0, 0, 16, 8)
    assert (px[0, :, :3] == 255).all() and (px[:, 15, :3] == 255).all()
    assert px[3, 5, 3] == 0  # the inside is left alone


def test_alpha_opacity_and_fills(display: Display) -> None:
    display.setColor(0x000000)
    display.fillRectangle(0, 0, 16, 8)
    display.setColor(0xFFFFFF)
    display.setOpacity(0.5)
    display.setAlpha(0.2)
    display.drawPixel(1, 1)
    assert display.pixels[1, 1].tolist() == [
        128,
        128,
        128,
        153,
    ]  # half of white over black; alpha 0.2·255 blended
    display.setOpacity(1.0)
    display.setAlpha(1.0)
    display.setColor(0x00FF00)
    display.fillPolygon([2, 6, 2], [0, 0, 4])  # right triangle: pixel centres x+y < 6 from (2, 0)
    px = display.pixels
    assert px[0, 2, 1] == 255 and px[2, 2, 1] == 255 and px[3, 2, 1] == 0 and px[3, 5, 1] == 0
    display.setColor(0xFF00FF)
    display.fillOval(12, 4, 2, 2)
    assert px[4, 12].tolist() == [255, 0, 255, 255] and px[4, 14, 0] == 255 and px[4, 15, 0] == 0
    display.setColor(0x123456)
    display.setColor(0x1000000)  # out of range: ignored with an error line
    display.drawPixel(15, 7)
    assert px[7, 15, :3].tolist() == [0x12, 0x34, 0x56]


def test_images_copy_paste_and_save_png(display: Display, tmp_path: Path) -> None:
    display.setColor(0xFF8000)
    display.fillRectangle(0, 0, 4, 4)
    copy = display.imageCopy(0, 0, 4, 4)
    display.imagePaste(copy, 8, 4, False)
    assert (display.pixels[4:8, 8:12] == [255, 128, 0, 255]).all()
    raw = bytes([0, 0, 255, 128] * 4)  # BGRA: red at half alpha
    img = display.imageNew(raw, Display.BGRA, 2, 2)
    display.imagePaste(img, 0, 6, True)  # blended over transparent black
    assert display.pixels[6, 0].tolist() == [128, 0, 0, 128]
    path = tmp_path / "screen.png"
    display.imageSave(None, str(path))
    assert (_read_png(path) == display.pixels).all()
    display.imageSave(copy, str(tmp_path / "copy.png"))
    assert _read_png(tmp_path / "copy.png").shape == (4, 4, 4)
    pil = pytest.importorskip("PIL.Image")
    with pil.open(path) as decoded:  # and a well-kept reader agrees
        assert (np.array(decoded.convert("RGBA")) == display.pixels).all()
    loaded = display.imageLoad(str(path))
    assert type(loaded) is int  # an opaque reference, as Webots' wrapper returns the image pointer
    display.imageSave(loaded, str(tmp_path / "loaded.png"))
    assert (_read_png(tmp_path / "loaded.png") == display.pixels).all()
    display.imageDelete(loaded)


def test_an_image_reference_the_display_did_not_make_is_an_error_line(
    display: Display, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    deleted = display.imageCopy(0, 0, 2, 2)
    display.imageDelete(deleted)
    before = display.pixels.copy()
    display.imagePaste(deleted, 0, 0, False)
    display.imageSave(12345, str(tmp_path / "none.png"))
    display.imageDelete(None)
    err = capsys.readouterr().err.splitlines()
    assert [line.split("(")[0] for line in err] == [
        "Warning: Display.imagePaste", "Warning: Display.imageSave", "Warning: Display.imageDelete"]
    assert (display.pixels == before).all() and not (tmp_path / "none.png").exists()


def test_an_image_that_cannot_be_made_is_none_with_an_error(display: Display, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """Webots' library prints an error and returns NULL; before, a negative size was a NumPy reshape error, a huge
    copy 'array is too big' and an unreadable file PIL's UnidentifiedImageError (tracebacks in the controller)."""
    not_an_image = tmp_path / "notes.png"
    not_an_image.write_text("not a picture")
    made = [display.imageNew(b"\0" * 12, Display.RGB, -2, -2), display.imageCopy(-5, -5, 2**31 - 1, 2**31 - 1),
            display.imageCopy(0, 0, 0, 3), display.imageLoad(str(not_an_image)),
            display.imageLoad(str(tmp_path / "missing.png"))]
    assert made == [None] * 5
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 5 and all(line.startswith("Warning: Display.image") for line in err), err
    assert "-2 x -2 pixels cannot be made" in err[0] and "notes.png" in err[3]
    # control: a copy reaching past the display is made, black where the display is not
    display.imageSave(display.imageCopy(14, 6, 4, 4), str(tmp_path / "edge.png"))
    assert _read_png(tmp_path / "edge.png").shape == (4, 4, 4)


def _bresenham(x1: int, y1: int, x2: int, y2: int) -> list[tuple[int, int]]:
    """The whole segment, walked by the error-term loop (the reference for the pixels a line lights)."""
    points, dx, dy = [], abs(x2 - x1), -abs(y2 - y1)
    sx, sy, err, x, y = (1 if x1 < x2 else -1), (1 if y1 < y2 else -1), dx + dy, x1, y1
    while True:
        points.append((x, y))
        if (x, y) == (x2, y2):
            return points
        e2 = 2 * err
        if e2 >= dy:
            err, x = err + dy, x + sx
        if e2 <= dx:
            err, y = err + dx, y + sy


def test_lines_light_the_pixels_of_the_whole_segment(display: Display) -> None:
    """Lines starting, ending or passing off the 16 x 8 display light exactly the on-display pixels of the
    whole segment, though only the visible steps are computed."""
    ends = [-40, -3, 0, 5, 7, 15, 16, 33, 1000]
    for x1, y1, x2, y2 in itertools.product(ends, ends[::2], ends[1::2], ends):
        display.pixels[:] = 0
        display.drawLine(x1, y1, x2, y2)
        want = {(x, y) for x, y in _bresenham(x1, y1, x2, y2) if 0 <= x < 16 and 0 <= y < 8}
        got = {(int(x), int(y)) for y, x in zip(*np.nonzero(display.pixels[:, :, 3]), strict=True)}
        assert got == want, (x1, y1, x2, y2)


HUGE_LINES = """
import resource, warnings
from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    sim = Simulation(load_world_text('#VRML_SIM R2023b utf8\\nRobot { supervisor TRUE children [ Display { name "d" '
                                     'width 16 height 8 } ] }'))
d = Supervisor(simulation=sim, robot_node=sim.robots[0].node).getDevice("d")
size = int(open("/proc/self/status").read().split("VmSize:")[1].split()[0]) * 1024
resource.setrlimit(resource.RLIMIT_AS, (size + (256 << 20), resource.RLIM_INFINITY))
big = 2**31 - 1
d.setColor(0xFFFFFF)
d.drawLine(0, 0, big, big)
d.drawRectangle(2, -big, big, big + 7)
d.drawPolygon([-big, big, big], [3, 3, big])
print(sorted((int(x), int(y)) for y, x in zip(*d.pixels[:, :, 3].nonzero())))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
def test_lines_with_huge_coordinates_cost_only_their_visible_part() -> None:
    """drawLine / drawRectangle / drawPolygon with coordinates near 2**31 (a controller's overflowed numbers)
    used to walk the whole segment point by point: the simulation hung and ate the memory. Run in a child whose
    address space may grow by 256 MiB only, so the old behaviour fails with MemoryError instead of a hang."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", HUGE_LINES], capture_output=True, text=True, env=env, cwd=ROOT,
                         timeout=120, check=False)
    assert out.returncode == 0, out.stderr[-2000:]
    diagonal = {(i, i) for i in range(8)}
    rectangle = {(2, y) for y in range(7)} | {(x, 6) for x in range(2, 16)}  # its left and bottom edges
    polygon = {(x, 3) for x in range(16)}  # its horizontal edge
    assert out.stdout.strip() == str(sorted(diagonal | rectangle | polygon)), out.stdout
