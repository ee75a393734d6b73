"""The project's one strict pydantic base: every typed config and every validated document derives from it.

Decisions:

* ``extra="forbid"``: a misspelt field in a config, a suite or a request is an error naming it, never
  silently ignored.
* ``allow_inf_nan=False``: a NaN or an infinity in a config is a mistake (JSON cannot even hold them; pydantic
  would write ``null``), so it is refused where it is read. Models whose values are *measured* (an analysis'
  sensitivities, which may be infinite when a perturbed run is unstable) opt back in with
  ``model_config = ConfigDict(allow_inf_nan=True)``; pydantic merges a subclass's config with its base's.
* Not ``strict=True``: JSON has no integer/float distinction worth enforcing (``1`` is a fine ``float``), and
  YAML documents arrive through the same models. Models that must refuse coercion (an LLM's reply, where
  ``"0.3"`` for a number is a mistake to report) add ``strict=True`` themselves.
* :class:`FrozenModel` for configs saved next to artifacts: a config is hashed (resume checks it), so it
  must not change after validation.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class StrictModel(BaseModel):
    """Unknown fields and non-finite numbers are validation errors."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class FrozenModel(StrictModel):
    """A :class:`StrictModel` that cannot be changed once validated (configs, specs, documents)."""

    model_config = ConfigDict(frozen=True)


__all__ = ["FrozenModel", "StrictModel"]
