"""A Transform's ``scale`` outside a boundingObject, as the converter can carry it.

Inside a boundingObject every scale is taken per axis (:func:`dualtwin.convert.mass.bounding_primitives`). Above
Solids and joints the converter needs one factor: a Solid's mass and inertia scale as s^3 and s^5 (on-ODE §3.2),
which a per-axis scale would shear, and a joint's anchor and a body's frame have no sheared counterpart in MuJoCo.
Above Shapes alone (what a Robot's drawing is made of) a per-axis scale is only drawn: the converter scales each
visual geom per axis as it does a boundingObject's (a Box's extents and a mesh's vertices per axis, the round
primitives by the largest factor). Above a Solid or joint a non-uniform scale acts as its largest factor, with a
warning, as in the Webots twin (:func:`dualtwin.webots.solid_scale.body_factor`), so the twins agree; it used to
stop the conversion of the whole world.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dualtwin.convert.mass import FloatArray, axis_scales
from dualtwin.webots.nodes import Node
from dualtwin.webots.solid_scale import body_factor, holds_bodies, positive_scale

__all__ = ["transform_scale"]


def transform_scale(transform: Node, warn: Callable[[str], None] = lambda _: None) -> float | FloatArray:
    """The Transform's scale: one factor when uniform, its three factors when it holds no Solid or joint, its largest
    factor (with a ``warn`` line) above a Solid or joint; a zero, negative or non-finite component is reset to 1, with
    a ``warn`` line: each as the Webots twin does (:mod:`dualtwin.webots.solid_scale`)."""
    positive = positive_scale(transform, warn)
    scales = axis_scales(positive)
    if np.allclose(scales, scales[0], rtol=1e-9, atol=0.0):
        return float(scales[0])
    if holds_bodies(transform):
        return float(body_factor(transform, positive, warn))
    return scales
