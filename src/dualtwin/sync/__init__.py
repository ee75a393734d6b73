"""Online synchronisation of twins: state transfer, lockstep runs, prediction error, drift monitoring.

The paper's synchronisation component: an agent between the simulators watches both, and when their states
drift apart it re-synchronises them or adjusts parameters. Pieces:

* state transfer: :meth:`Twin.get_state` / :meth:`Twin.set_state` (:class:`MechanicalState`, in
  :mod:`dualtwin.twins.base`), exact to floating-point precision on MuJoCo and through the Webots
  supervisor API;
* :func:`run_lockstep`: both twins get the same commands every control period, with a re-sync policy
  (``never``, ``every:N``, ``threshold:X``), per-channel state differences logged;
* :func:`dualtwin.divergence.prediction.prediction_error`: k-step prediction error from synchronised start
  states (multiple shooting), also an alignment objective (``dualtwin.align.run_align`` with
  ``AlignConfig(objective="prediction", ...)``);
* :class:`Monitor`: sliding-window statistics, a drift alarm with hysteresis, an event log and background
  re-alignment applied at episode boundaries;
* :func:`write_sync_report`: HTML + JSON of prediction curves, drift, alarms and re-alignments.

The measuring primitives (state-difference channels, recorded trajectories, the prediction error) live in
:mod:`dualtwin.divergence` so that :mod:`dualtwin.align` can use them without importing upwards; import
them from there (this package does not re-export them, so each name has one home). The state types
(:class:`MechanicalState`, :class:`BodyState`, :class:`SyncError`) are imported from
:mod:`dualtwin.twins.base`. The Webots shadow of RL training (:class:`dualtwin.rl.shadow.ShadowCallback`) is
a piece of training and lives in :mod:`dualtwin.rl`; it feeds a :class:`Monitor` through a protocol.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from dualtwin.sync.lockstep import EpisodeSummary, LockstepResult, ResyncPolicy, run_lockstep
from dualtwin.sync.monitor import Monitor, MonitorConfig, RealignSettings, read_events

if TYPE_CHECKING:
    from dualtwin.sync.report import write_sync_report


def __getattr__(name: str) -> Any:
    # Lazy: the report pulls in matplotlib.
    if name == "write_sync_report":
        from dualtwin.sync.report import write_sync_report

        return write_sync_report
    raise AttributeError(f"module 'dualtwin.sync' has no attribute {name!r}")


__all__ = [
    "EpisodeSummary", "LockstepResult", "Monitor", "MonitorConfig", "RealignSettings", "ResyncPolicy",
    "read_events", "run_lockstep", "write_sync_report",
]
