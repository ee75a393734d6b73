"""The objective's weights and robustness settings (:class:`ObjectiveWeights`), a field of ``AlignConfig``.

Apart from :mod:`dualtwin.align.objective` (which computes with them) so that the configuration, and the
command-line options derived from it, load without NumPy, SciPy or the simulators.
"""

from __future__ import annotations

from pydantic import Field

from dualtwin.models import FrozenModel

#: The objective's terms, in the order reports list them (see :mod:`dualtwin.align.objective`).
TERMS = ("dtw", "event", "endpoint", "rmse")


class ObjectiveWeights(FrozenModel):
    """Weights and robustness settings of the objective (see :mod:`dualtwin.align.objective`)."""

    dtw: float = Field(default=1.0, ge=0)
    event: float = Field(default=1.0, ge=0)
    endpoint: float = Field(default=0.5, ge=0)
    rmse: float = Field(default=0.0, ge=0)
    trajectory: float = Field(default=1.0, ge=0, description="least squares: weight of trajectory residuals")
    robust_delta: float = Field(default=0.05, gt=0, description="pseudo-Huber transition, in term units")
    unstable_penalty: float = Field(default=10.0, gt=0)

    def term_weights(self) -> dict[str, float]:
        return {name: float(getattr(self, name)) for name in TERMS}
