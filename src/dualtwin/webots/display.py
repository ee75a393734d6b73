"""Display: Webots' drawing API on an RGBA frame buffer, headless.

The buffer is ``height × width`` RGBA, pixel (0, 0) at the top-left, transparent black at start. Webots queues
every call but ``getWidth``/``getHeight`` and runs them in order at the next step; here they run at once, in the
same order, which gives the same pixels — the only difference is that a file written by ``imageSave`` exists
before ``step`` returns rather than after it.

Context: ``setColor(0xRRGGBB)`` (default white), ``setAlpha`` (the alpha written with the colour, default 1),
``setOpacity`` (how much a new pixel covers the old one, default 1: ``out = o·new + (1−o)·old``). Drawing:
pixels, Bresenham lines, rectangle/oval/polygon outlines and fills (even-odd rule at pixel centres);
coordinates are cast with ``int()`` as Webots' Python wrapper does. Text is not rasterised headless (no font
files; ``drawText`` and ``setFont`` only check their arguments), and ``attachCamera`` shows nothing.

Images: ``imageNew`` (RGB, RGBA, ARGB, BGRA or ABGR bytes), ``imageCopy`` of a display region, ``imagePaste``
(with ``blend``: alpha compositing, else a plain copy), ``imageSave`` (a real PNG: RGBA, 8 bit, zlib, written
atomically; ``None`` saves the whole display), ``imageLoad`` (PNG through Pillow, when installed), ``imageDelete``.
An image is referred to by an opaque ``int``, as Webots' Python wrapper returns the C library's image pointer as an
``int`` (unique in the process: 1, 2, ...); a reference this display did not make is an error line, and ignored.
"""

from __future__ import annotations

import itertools
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import write_bytes
from dualtwin.errors import DualtwinError
from dualtwin.webots.api_args import as_float, as_int, as_text, error, warn
from dualtwin.webots.device_base import Device
from dualtwin.webots.protos import MAX_IMAGE_SIDE  # (the world loader's cap on a Display's own size)

__all__ = ["Display", "png_bytes"]

_IMAGE_REFS = itertools.count(1)  # image references, unique in the process as Webots' image pointers are


def png_bytes(rgba: np.ndarray) -> bytes:
    """An RGBA uint8 image (height, width, 4) encoded as PNG (filter 0 on every row)."""
    h, w, _ = rgba.shape
    raw = b"".join(b"\x00" + rgba[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data))
            + kind
            + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        )

    header = struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0)  # 8-bit RGBA, no interlace
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw, 9))
        + chunk(b"IEND", b"")
    )


def _image_size_ok(width: int, height: int, method: str) -> bool:
    """Webots' library prints an error and returns NULL for an image it cannot make; so do we (a negative or
    huge size was a NumPy error, or gigabytes allocated)."""
    if 0 < width <= MAX_IMAGE_SIDE and 0 < height <= MAX_IMAGE_SIDE:
        return True
    warn(f"{method}: an image of {width} x {height} pixels cannot be made (each side 1 to {MAX_IMAGE_SIDE}); "
         "no image made")
    return False


class Display(Device):
    """Webots ``Display`` (see the module docstring)."""

    RGB = 3
    RGBA = 4
    ARGB = 5
    BGRA = 6
    ABGR = 7

    def _setup(self) -> None:
        f = self._record.node.fields
        robot = self._robot
        self._w = max(1, int(f.get("width", 64)))
        self._h = max(1, int(f.get("height", 64)))
        self.pixels = np.zeros((self._h, self._w, 4), dtype=np.uint8)
        self._color = (255, 255, 255)
        self._alpha = 1.0
        self._opacity = 1.0
        self._images: dict[int, np.ndarray] = {}  # image reference -> RGBA pixels
        robot._sim.reset_hooks.append(self._clear)

    def _clear(self) -> None:
        """simulationReset clears the display (Webots' reset matrix); images and context are controller-side."""
        self.pixels[:] = 0

    # -- context

    def getWidth(self) -> int:
        return self._w

    def getHeight(self) -> int:
        return self._h

    def setColor(self, color: Any) -> None:
        c = as_int(color, "Display.setColor")
        if not 0 <= c <= 0xFFFFFF:
            error(f"Display.setColor(): color {c:#x} out of range [0, 0xFFFFFF]")
            return
        self._color = ((c >> 16) & 0xFF, (c >> 8) & 0xFF, c & 0xFF)

    def setAlpha(self, alpha: Any) -> None:
        a = as_float(alpha, "Display.setAlpha")
        if not 0.0 <= a <= 1.0:
            warn(f"Display.setAlpha(): {a} out of range [0, 1]")
            return
        self._alpha = a

    def setOpacity(self, opacity: Any) -> None:
        o = as_float(opacity, "Display.setOpacity")
        if not 0.0 <= o <= 1.0:
            warn(f"Display.setOpacity(): {o} out of range [0, 1]")
            return
        self._opacity = o

    def setFont(self, font: str, size: Any, anti_aliasing: bool) -> None:
        as_text(font, "Display.setFont")
        if as_int(size, "Display.setFont") <= 0:
            warn("Display.setFont(): the size must be > 0")

    def attachCamera(self, camera: Any) -> None:
        pass  # headless: no camera image to show

    def detachCamera(self) -> None:
        pass

    # -- drawing

    def _paint(self, mask: np.ndarray) -> None:
        """Apply the context's colour, alpha and opacity where ``mask`` (height × width) is set."""
        new = np.array([*self._color, round(self._alpha * 255)], dtype=float)
        old = self.pixels[mask].astype(float)
        self.pixels[mask] = np.clip(
            np.rint(self._opacity * new + (1.0 - self._opacity) * old), 0, 255
        ).astype(np.uint8)

    def _points(self, points: list[tuple[int, int]]) -> None:
        mask = np.zeros((self._h, self._w), dtype=bool)
        for x, y in points:
            if 0 <= x < self._w and 0 <= y < self._h:
                mask[y, x] = True
        self._paint(mask)

    def _line(self, x1: int, y1: int, x2: int, y2: int) -> list[tuple[int, int]]:
        """The pixels of the segment that can be on the display: those of the error-term Bresenham loop (the
        one stepping x when 2*err >= dy and y when 2*err <= dx), computed in closed form for the steps whose
        major coordinate is on the display only. Walking the whole segment instead made a line to (2**31-1,
        2**31-1) build two billion points: the simulation hung and ran out of memory."""
        dx, dy = abs(x2 - x1), abs(y2 - y1)
        sx, sy = (1 if x1 < x2 else -1), (1 if y1 < y2 else -1)
        n = max(dx, dy)
        # at step k the major coordinate has moved k times and the minor one floor((2*minor*k + major) /
        # (2*major)) times: the loop's ties (2*err == dy or dx) step both, which the floor reproduces
        if dx >= dy:
            lo, hi = _visible_steps(x1, sx, n, self._w)
            return [(x1 + sx * k, y1 + sy * ((2 * dy * k + dx) // (2 * dx) if dx else 0)) for k in range(lo, hi)]
        lo, hi = _visible_steps(y1, sy, n, self._h)
        return [(x1 + sx * ((2 * dx * k + dy) // (2 * dy)), y1 + sy * k) for k in range(lo, hi)]

    def drawPixel(self, x: Any, y: Any) -> None:
        self._points([(int(x), int(y))])

    def drawLine(self, x1: Any, y1: Any, x2: Any, y2: Any) -> None:
        self._points(self._line(int(x1), int(y1), int(x2), int(y2)))

    def drawRectangle(self, x: Any, y: Any, width: Any, height: Any) -> None:
        x, y, w, h = int(x), int(y), int(width), int(height)
        if w <= 0 or h <= 0:
            return
        corners = [(x, y), (x + w - 1, y), (x + w - 1, y + h - 1), (x, y + h - 1)]
        self._polyline(corners)

    def fillRectangle(self, x: Any, y: Any, width: Any, height: Any) -> None:
        x, y, w, h = int(x), int(y), int(width), int(height)
        mask = np.zeros((self._h, self._w), dtype=bool)
        mask[max(y, 0) : max(y + h, 0), max(x, 0) : max(x + w, 0)] = True
        self._paint(mask)

    def _oval_mask(self, cx: int, cy: int, a: int, b: int, fill: bool) -> np.ndarray:
        ys, xs = np.mgrid[0 : self._h, 0 : self._w]
        a, b = max(a, 0), max(b, 0)
        if a == 0 or b == 0:
            return (xs == cx) & (np.abs(ys - cy) <= b) | (ys == cy) & (np.abs(xs - cx) <= a)
        inside = ((xs - cx) / a) ** 2 + ((ys - cy) / b) ** 2 <= 1.0
        if fill:
            return inside
        # the outline: inside pixels with a 4-neighbour outside
        pad = np.pad(inside, 1, constant_values=False)
        interior = pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:]
        return inside & ~interior

    def drawOval(self, cx: Any, cy: Any, a: Any, b: Any) -> None:
        self._paint(self._oval_mask(int(cx), int(cy), int(a), int(b), fill=False))

    def fillOval(self, cx: Any, cy: Any, a: Any, b: Any) -> None:
        self._paint(self._oval_mask(int(cx), int(cy), int(a), int(b), fill=True))

    def _polyline(self, pts: list[tuple[int, int]]) -> None:
        points: list[tuple[int, int]] = []
        for i, (x1, y1) in enumerate(pts):
            x2, y2 = pts[(i + 1) % len(pts)]
            points += self._line(x1, y1, x2, y2)
        self._points(points)

    def drawPolygon(self, x: Any, y: Any) -> None:
        pts = [(int(a), int(b)) for a, b in zip(x, y, strict=True)]
        if pts:
            self._polyline(pts)

    def fillPolygon(self, x: Any, y: Any) -> None:
        pts = [(float(int(a)), float(int(b))) for a, b in zip(x, y, strict=True)]
        if len(pts) < 3:
            return
        ys, xs = np.mgrid[0 : self._h, 0 : self._w]
        px, py = xs + 0.5, ys + 0.5
        inside = np.zeros((self._h, self._w), dtype=bool)
        for (x1, y1), (x2, y2) in zip(pts, pts[1:] + pts[:1], strict=True):
            if y1 == y2:
                continue
            crosses = (py >= min(y1, y2)) & (py < max(y1, y2))
            xcross = x1 + (py - y1) * (x2 - x1) / (y2 - y1)
            inside ^= crosses & (px < xcross)
        self._paint(inside)

    def drawText(self, text: str, x: Any, y: Any) -> None:
        as_text(text, "Display.drawText")
        int(x), int(y)  # argument check only: no font rasteriser headless

    # -- images

    def _ref(self, pixels: np.ndarray) -> int:
        ref = next(_IMAGE_REFS)
        self._images[ref] = pixels
        return ref

    def _pixels(self, image: Any, method: str) -> np.ndarray | None:
        pixels = self._images.get(image) if isinstance(image, int) else None
        if pixels is None:
            warn(f"Display.{method}(): {image!r} is not an image of this display (see imageNew, imageCopy, "
                 "imageLoad); ignored")
        return pixels

    def imageNew(self, data: Any, format: Any, width: Any, height: Any) -> int | None:  # noqa: A002
        fmt = as_int(format, "Display.imageNew")
        w, h = int(width), int(height)
        channels = 3 if fmt == self.RGB else 4
        if fmt not in (self.RGB, self.RGBA, self.ARGB, self.BGRA, self.ABGR):
            raise ValueError(f"Display.imageNew(): unknown format {fmt}")
        if not _image_size_ok(w, h, "Display.imageNew()"):
            return None
        raw = np.frombuffer(bytes(data) if not isinstance(data, np.ndarray) else data.astype(np.uint8).tobytes(),
                            dtype=np.uint8)  # fmt: skip
        if raw.size != w * h * channels:
            raise ValueError(f"Display.imageNew(): expected {w * h * channels} bytes, got {raw.size}")
        img = raw.reshape(h, w, channels)
        if fmt == self.RGB:
            rgba = np.concatenate([img, np.full((h, w, 1), 255, dtype=np.uint8)], axis=2)
        else:
            order = {
                self.RGBA: [0, 1, 2, 3],
                self.ARGB: [1, 2, 3, 0],
                self.BGRA: [2, 1, 0, 3],
                self.ABGR: [3, 2, 1, 0],
            }
            rgba = img[:, :, order[fmt]]
        return self._ref(np.ascontiguousarray(rgba))

    def imageLoad(self, filename: str) -> int | None:
        try:
            from PIL import Image
        except ImportError as exc:  # pragma: no cover - Pillow is installed with the server extra
            raise DualtwinError("Display.imageLoad needs Pillow (pip install pillow)") from exc
        try:
            with Image.open(Path(filename), formats=["PNG", "JPEG"]) as img:
                if not _image_size_ok(img.width, img.height, "Display.imageLoad()"):
                    return None
                return self._ref(np.array(img.convert("RGBA"), dtype=np.uint8))
        except (OSError, ValueError, Image.DecompressionBombError) as exc:  # (UnidentifiedImageError is an OSError)
            warn(f"Display.imageLoad(): cannot load {filename!r} as a PNG or JPEG image ({exc}); no image made")
            return None

    def imageCopy(self, x: Any, y: Any, width: Any, height: Any) -> int | None:
        x, y, w, h = int(x), int(y), int(width), int(height)
        if not _image_size_ok(w, h, "Display.imageCopy()"):
            return None
        out = np.zeros((h, w, 4), dtype=np.uint8)
        x0, y0 = max(x, 0), max(y, 0)
        x1, y1 = min(x + w, self._w), min(y + h, self._h)
        if x1 > x0 and y1 > y0:
            out[y0 - y : y1 - y, x0 - x : x1 - x] = self.pixels[y0:y1, x0:x1]
        return self._ref(out)

    def imagePaste(self, image: int, x: Any, y: Any, blend: bool) -> None:
        x, y = int(x), int(y)
        src = self._pixels(image, "imagePaste")
        if src is None:
            return
        h, w = src.shape[:2]
        x0, y0 = max(x, 0), max(y, 0)
        x1, y1 = min(x + w, self._w), min(y + h, self._h)
        if x1 <= x0 or y1 <= y0:
            return
        part = src[y0 - y : y1 - y, x0 - x : x1 - x].astype(float)
        dst = self.pixels[y0:y1, x0:x1].astype(float)
        if blend:
            a = part[:, :, 3:4] / 255.0
            rgb = part[:, :, :3] * a + dst[:, :, :3] * (1.0 - a)
            alpha = part[:, :, 3:4] + dst[:, :, 3:4] * (1.0 - a)
            part = np.concatenate([rgb, alpha], axis=2)
        self.pixels[y0:y1, x0:x1] = np.clip(np.rint(part), 0, 255).astype(np.uint8)

    def imageSave(self, image: int | None, filename: str) -> None:
        pixels = self.pixels if image is None else self._pixels(image, "imageSave")
        if pixels is not None:
            write_bytes(Path(filename), png_bytes(pixels))

    def imageDelete(self, image: int) -> None:
        if self._pixels(image, "imageDelete") is not None:
            del self._images[image]

    width = property(lambda self: self.getWidth())
    height = property(lambda self: self.getHeight())
    alpha = property(fset=lambda self, alpha: self.setAlpha(alpha))
    color = property(fset=lambda self, color: self.setColor(color))
    opacity = property(fset=lambda self, opacity: self.setOpacity(opacity))


def _visible_steps(start: int, step: int, n: int, size: int) -> tuple[int, int]:
    """The steps ``k`` of ``[0, n]`` where ``0 <= start + step * k < size`` (``step`` is ±1), as ``range(lo, hi)``."""
    lo, hi = (-start, size - start) if step > 0 else (start - size + 1, start + 1)
    return max(lo, 0), min(hi, n + 1)
