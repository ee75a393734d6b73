"""A Transform's ``scale`` outside a boundingObject, as the converter can carry it.

Inside a boundingObject every scale is taken per axis (:func:`dualtwin.convert.mass.bounding_primitives`). Above
Solids and joints the converter needs one factor: a Solid's mass and inertia scale as s^3 and s^5 (on-ODE §3.2),
which a per-axis scale would shear, and a joint's anchor and a body's frame have no sheared counterpart in MuJoCo.
Above Shapes alone (what a Robot's drawing is made of) a per-axis scale is only drawn: the converter scales each
visual geom per axis as it does a boundingObject's (a Box's extents and a mesh's vertices per axis, the round
primitives by the largest factor). Such a Transform used to stop the conversion of the whole world; above a
Solid or joint it still does.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dualtwin.convert.conversion import ConversionError
from dualtwin.convert.mass import FloatArray, axis_scales
from dualtwin.webots import schema
from dualtwin.webots.nodes import Node
from dualtwin.webots.solid_scale import positive_scale

__all__ = ["transform_scale"]


def transform_scale(transform: Node, warn: Callable[[str], None] = lambda _: None) -> float | FloatArray:
    """The Transform's scale: one factor when uniform, its three factors when it holds no Solid or joint; a zero,
    negative or non-finite component is reset to 1, with a ``warn`` line, as the Webots twin does
    (:func:`dualtwin.webots.solid_scale.positive_scale`).

    Raises:
        ConversionError: a non-uniform scale above a Solid or a joint.
    """
    scales = axis_scales(positive_scale(transform, warn))
    if np.allclose(scales, scales[0], rtol=1e-9, atol=0.0):
        return float(scales[0])
    if any(schema.is_solid_type(n.type_name) or n.type_name in schema.JOINT_TYPES for n in transform.walk()):
        where = str(transform.location) if transform.location is not None else "<unknown location>"
        sx, sy, sz = scales
        raise ConversionError(f"{where}: unsupported node Transform (non-uniform scale {sx:g} {sy:g} {sz:g} above a "
                              "Solid or joint); the converter cannot map it to MuJoCo")
    return scales
