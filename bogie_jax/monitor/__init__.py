"""Condition monitoring: verdicts per suspension element and trends over dated runs."""

from ._trend import Trend as Trend, trend as trend, two_sided_p_value as two_sided_p_value
from ._verdict import (
    VERDICTS as VERDICTS,
    ToleranceBand as ToleranceBand,
    Verdict as Verdict,
    decision_z as decision_z,
    judge as judge,
)
