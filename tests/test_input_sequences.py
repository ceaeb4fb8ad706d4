"""Sequences of model objects at public entry points: empty or mistyped input is named before
anything compiles."""

import pytest

from bogie_jax._validation import nonempty_tuple
from bogie_jax.cost import joint_residual_model
from bogie_jax.measure._layout import check_sensor_names
from bogie_jax.monitor._checks import as_measurements


def test_nonempty_tuple_returns_the_entries_as_a_tuple():
    assert nonempty_tuple("xs", iter([1, 2]), int, "give one") == (1, 2)


def test_nonempty_tuple_names_an_empty_argument_and_the_hint():
    with pytest.raises(ValueError, match=r"`xs` is empty: give one"):
        nonempty_tuple("xs", [], int, "give one")


def test_nonempty_tuple_names_the_first_entry_of_another_type():
    with pytest.raises(TypeError, match=r"`xs\[1\]` must be an int, got str"):
        nonempty_tuple("xs", [1, "a", "b"], int, "give one")


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: as_measurements([]), r"`measurements` is empty"),
        (lambda: as_measurements(["run.csv"]), r"`measurements\[0\]` must be a Measurement"),
        (lambda: joint_residual_model([]), r"`models` is empty"),
        (lambda: joint_residual_model([None]), r"`models\[0\]` must be a ResidualModel"),
        (lambda: check_sensor_names([]), r"`sensors` is empty"),
        (lambda: check_sensor_names(["lat"]), r"`sensors\[0\]` must be an AbstractSensor"),
    ],
)
def test_entry_points_name_bad_sequences(call, message):
    with pytest.raises((ValueError, TypeError), match=message):
        call()
