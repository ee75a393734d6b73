"""The period loop's signal values, computed once per signal document and shared by every twin that runs it."""

from __future__ import annotations

import math

from dualtwin.suite.runner import signal_values
from dualtwin.suite.signals import Impulse, Ramp, Sine, Step, Table


def test_values_are_the_signal_at_each_period_and_shared_by_equal_documents() -> None:
    signals = [Sine(kind="sine", amplitude=0.4, frequency_hz=3.0, phase_rad=0.1),
               Step(kind="step", at_s=0.1, after=1.0), Impulse(kind="impulse", at_s=0.05, duration_s=0.03, value=2.0),
               Ramp(kind="ramp", start_s=0.0, end_s=0.2, end=1.5),
               Table(kind="table", points=[(0.0, 1.0), (0.1, -1.0)], interpolation="linear")]
    for signal in signals:
        values = signal_values(signal, 0.016, 25)
        assert values == [signal(k * 0.016) for k in range(25)]
        # An equal document parsed again (as each scenario access does) shares the values computed once.
        assert signal_values(type(signal).model_validate(signal.model_dump()), 0.016, 25) is values
    # Documents that differ in any field, or another period or length, get their own values.
    a = signal_values(Sine(kind="sine", amplitude=0.4, frequency_hz=3.0), 0.016, 25)
    b = signal_values(Sine(kind="sine", amplitude=0.4 + 1e-15, frequency_hz=3.0), 0.016, 25)
    assert a != b and a[5] != b[5]
    assert signal_values(Sine(kind="sine", amplitude=0.4, frequency_hz=3.0), 0.032, 25)[1] == 0.4 * math.sin(
        2 * math.pi * 3.0 * 0.032)
    assert len(signal_values(Sine(kind="sine", amplitude=0.4, frequency_hz=3.0), 0.016, 7)) == 7
