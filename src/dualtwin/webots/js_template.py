"""The JavaScript side of procedural PROTO templates: Webots' template modules and value literals.

Webots' templates may ``import`` its modules (``wbutility``, ``wbvector2``, ``wbvector3``, ``wbrotation``,
``wbgeometry``, ``wbrandom``). We provide minimal versions written for dualtwin (same function names) and
replace ``import`` lines by bindings to them, so a template can never load other code: an unknown module is a
JavaScript error. :mod:`dualtwin.webots.protos` builds the program and runs it in QuickJS.
"""

from __future__ import annotations

import json
import math
import re

__all__ = ["JS_MODULES", "VEC_KEYS", "js_number", "strip_imports"]

# Minimal versions of Webots' template modules, written for dualtwin (same function names).
JS_MODULES = r"""
const __wbmodules = (function () {
  const isObj = (v) => v !== null && typeof v === 'object';
  const hasKeys = (v, keys) => isObj(v) && Object.keys(v).length === keys.length &&
    keys.every((k) => typeof v[k] === 'number');
  const wbutility = {
    isScalar: (v) => typeof v === 'number',
    isVector2: (v) => hasKeys(v, ['x', 'y']),
    isVector3: (v) => hasKeys(v, ['x', 'y', 'z']),
    isColor: (v) => hasKeys(v, ['r', 'g', 'b']),
    isRotation: (v) => hasKeys(v, ['x', 'y', 'z', 'a']),
    isArray: (v) => Array.isArray(v),
    deepCopy: (v) => JSON.parse(JSON.stringify(v)),
    clamp: (v, lo, hi) => Math.min(Math.max(v, lo), hi),
  };
  const wbvector2 = {
    add: (a, b) => ({x: a.x + b.x, y: a.y + b.y}),
    minus: (a, b) => ({x: a.x - b.x, y: a.y - b.y}),
    multiply: (a, s) => ({x: a.x * s, y: a.y * s}),
    dot: (a, b) => a.x * b.x + a.y * b.y,
    cross: (a, b) => a.x * b.y - a.y * b.x,
    norm: (a) => Math.hypot(a.x, a.y),
    normalize: (a) => { const n = Math.hypot(a.x, a.y); return n > 0 ? {x: a.x / n, y: a.y / n} : {x: 0, y: 0}; },
    distance: (a, b) => Math.hypot(a.x - b.x, a.y - b.y),
    angle: (a, b) => Math.atan2(b.y, b.x) - Math.atan2(a.y, a.x),
    equal: (a, b) => a.x === b.x && a.y === b.y,
  };
  const wbvector3 = {
    add: (a, b) => ({x: a.x + b.x, y: a.y + b.y, z: a.z + b.z}),
    minus: (a, b) => ({x: a.x - b.x, y: a.y - b.y, z: a.z - b.z}),
    multiply: (a, s) => ({x: a.x * s, y: a.y * s, z: a.z * s}),
    dot: (a, b) => a.x * b.x + a.y * b.y + a.z * b.z,
    cross: (a, b) => ({x: a.y * b.z - a.z * b.y, y: a.z * b.x - a.x * b.z, z: a.x * b.y - a.y * b.x}),
    norm: (a) => Math.hypot(a.x, a.y, a.z),
    normalize: (a) => {
      const n = Math.hypot(a.x, a.y, a.z);
      return n > 0 ? {x: a.x / n, y: a.y / n, z: a.z / n} : {x: 0, y: 0, z: 0};
    },
    distance: (a, b) => Math.hypot(a.x - b.x, a.y - b.y, a.z - b.z),
    equal: (a, b) => a.x === b.x && a.y === b.y && a.z === b.z,
  };
  const toQuaternion = (r) => {
    const n = Math.hypot(r.x, r.y, r.z) || 1;
    const s = Math.sin(r.a / 2);
    return {w: Math.cos(r.a / 2), x: s * r.x / n, y: s * r.y / n, z: s * r.z / n};
  };
  const fromQuaternion = (q) => {
    const n = Math.hypot(q.w, q.x, q.y, q.z) || 1;
    const w = Math.max(-1, Math.min(1, q.w / n));
    const a = 2 * Math.acos(w);
    const s = Math.sqrt(Math.max(0, 1 - w * w));
    if (s < 1e-12) return {x: 0, y: 0, z: 1, a: 0};
    return {x: q.x / n / s, y: q.y / n / s, z: q.z / n / s, a: a};
  };
  const quaternionMultiply = (p, q) => ({
    w: p.w * q.w - p.x * q.x - p.y * q.y - p.z * q.z,
    x: p.w * q.x + p.x * q.w + p.y * q.z - p.z * q.y,
    y: p.w * q.y - p.x * q.z + p.y * q.w + p.z * q.x,
    z: p.w * q.z + p.x * q.y - p.y * q.x + p.z * q.w,
  });
  const toMatrix3 = (r) => {
    const q = toQuaternion(r);
    const {w, x, y, z} = q;
    return [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
            2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
            2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)];
  };
  const fromRotationMatrix = (m) => {
    const t = m[0] + m[4] + m[8];
    let q;
    if (t > 0) {
      const s = Math.sqrt(t + 1) * 2;
      q = {w: s / 4, x: (m[7] - m[5]) / s, y: (m[2] - m[6]) / s, z: (m[3] - m[1]) / s};
    } else if (m[0] > m[4] && m[0] > m[8]) {
      const s = Math.sqrt(1 + m[0] - m[4] - m[8]) * 2;
      q = {w: (m[7] - m[5]) / s, x: s / 4, y: (m[1] + m[3]) / s, z: (m[2] + m[6]) / s};
    } else if (m[4] > m[8]) {
      const s = Math.sqrt(1 + m[4] - m[0] - m[8]) * 2;
      q = {w: (m[2] - m[6]) / s, x: (m[1] + m[3]) / s, y: s / 4, z: (m[5] + m[7]) / s};
    } else {
      const s = Math.sqrt(1 + m[8] - m[0] - m[4]) * 2;
      q = {w: (m[3] - m[1]) / s, x: (m[2] + m[6]) / s, y: (m[5] + m[7]) / s, z: s / 4};
    }
    return fromQuaternion(q);
  };
  const rotateVector3ByMatrix3 = (m, v) => ({
    x: m[0] * v.x + m[1] * v.y + m[2] * v.z,
    y: m[3] * v.x + m[4] * v.y + m[5] * v.z,
    z: m[6] * v.x + m[7] * v.y + m[8] * v.z,
  });
  const wbrotation = {
    equal: (a, b) => a.x === b.x && a.y === b.y && a.z === b.z && a.a === b.a,
    isIdentity: (r) => r.a === 0,
    toQuaternion, fromQuaternion, quaternionMultiply, toMatrix3, fromRotationMatrix,
    rotateVector3ByMatrix3,
    rotateVector3ByRotation: (r, v) => rotateVector3ByMatrix3(toMatrix3(r), v),
    rotateVector3ByQuaternion: (q, v) => rotateVector3ByMatrix3(toMatrix3(fromQuaternion(q)), v),
    combine: (a, b) => fromQuaternion(quaternionMultiply(toQuaternion(a), toQuaternion(b))),
  };
  const wbgeometry = {
    circle: (radius, div, cx = 0, cy = 0, shift = 0) => {
      const out = [];
      for (let i = 0; i < div; ++i) {
        const a = shift + 2 * Math.PI * i / div;
        out.push({x: cx + radius * Math.cos(a), y: cy + radius * Math.sin(a)});
      }
      return out;
    },
    isPoint2InTriangle: (p, a, b, c) => {
      const s = (p1, p2, p3) => (p1.x - p3.x) * (p2.y - p3.y) - (p2.x - p3.x) * (p1.y - p3.y);
      const d1 = s(p, a, b), d2 = s(p, b, c), d3 = s(p, c, a);
      return !((d1 < 0 || d2 < 0 || d3 < 0) && (d1 > 0 || d2 > 0 || d3 > 0));
    },
  };
  let state = 1;
  const next = () => {  // mulberry32: deterministic, seedable
    state = (state + 0x6D2B79F5) | 0;
    let t = Math.imul(state ^ (state >>> 15), 1 | state);
    t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
  const wbrandom = {
    seed: (s) => { state = s | 0; },
    real: (lo, hi) => {
      if (lo === undefined) return next();
      if (hi === undefined) return next() * lo;
      return lo + next() * (hi - lo);
    },
    integer: (lo, hi) => {
      if (hi === undefined) { hi = lo; lo = 0; }
      return lo + Math.floor(next() * (hi - lo + 1));
    },
  };
  return {wbutility, wbvector2, wbvector3, wbrotation, wbgeometry, wbrandom};
})();
var wbutility = __wbmodules.wbutility, wbvector2 = __wbmodules.wbvector2,
  wbvector3 = __wbmodules.wbvector3, wbrotation = __wbmodules.wbrotation,
  wbgeometry = __wbmodules.wbgeometry, wbrandom = __wbmodules.wbrandom;
"""

# `^[ \t]*` rather than `^\s*`: a `\s*` after `^` (re.M) runs over the following blank lines from every line
# start, so a template of many blank lines was quadratic (300 000 newlines hung the load).
_IMPORT_STAR = re.compile(r"""^[ \t]*+import\s+\*\s+as\s+(\w+)\s+from\s+['"]([^'"]+)['"]\s*;?""", re.M)
_IMPORT_NAMED = re.compile(r"""^[ \t]*+import\s+\{([^}]*)\}\s+from\s+['"]([^'"]+)['"]\s*;?""", re.M)


def _module_name(spec: str) -> str:
    base = spec.replace("\\", "/").rsplit("/", 1)[-1]
    return base[:-3] if base.endswith(".js") else base


def strip_imports(code: str) -> str:
    """Replace ``import`` lines by bindings to the pre-defined modules (unknown module -> JS error)."""

    def star(m: re.Match[str]) -> str:
        return f"const {m.group(1)} = __wbmodules[{json.dumps(_module_name(m.group(2)))}];"

    def named(m: re.Match[str]) -> str:
        names = m.group(1).replace(" as ", ": ")
        return f"const {{{names}}} = __wbmodules[{json.dumps(_module_name(m.group(2)))}];"

    return _IMPORT_NAMED.sub(named, _IMPORT_STAR.sub(star, code))


def js_number(value: float | int) -> str:
    if isinstance(value, int):
        return str(value)
    if math.isnan(value):
        return "NaN"
    if math.isinf(value):
        return "Infinity" if value > 0 else "-Infinity"
    return repr(value)


VEC_KEYS = {"SFVec2f": "xy", "SFVec3f": "xyz", "SFColor": "rgb"}
