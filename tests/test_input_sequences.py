"""Sequences of model objects at public entry points: an empty one, or an entry of another
type, is named before anything compiles."""

import pytest

from bogie_jax.cost import joint_residual_model
from bogie_jax.measure import layout_description
from bogie_jax.monitor import monitor


CASES = [
    (monitor, [], ValueError, r"`measurements` is empty: give at least one"),
    (monitor, ["run.csv"], TypeError, r"`measurements\[0\]` must be a Measurement, got str"),
    (joint_residual_model, [], ValueError, r"`models` is empty: a joint objective"),
    (joint_residual_model, [None], TypeError, r"`models\[0\]` must be a ResidualModel"),
    (layout_description, [], ValueError, r"`sensors` is empty: give at least one sensor"),
    (layout_description, ["lat"], TypeError, r"`sensors\[0\]` must be an AbstractSensor"),
]


@pytest.mark.parametrize(("entry", "given", "error", "message"), CASES)
def test_entry_points_name_bad_sequences(entry, given, error, message):
    with pytest.raises(error, match=message):
        entry(given)
