"""Parameter modules: units, bounds, named sets and clear errors for invalid values."""

import math

import jax
import numpy as np
import pytest

import bogie_jax as bj
from bogie_jax.params import (
    BodyInertia,
    PARAMETER_SETS,
    parameter_names,
    parameter_specs,
    ParameterError,
    PrimarySuspension,
)


@pytest.mark.parametrize("name", sorted(PARAMETER_SETS))
def test_named_sets_are_valid_and_inside_their_valid_ranges(name):
    params = PARAMETER_SETS[name]()
    specs = parameter_specs(params)
    leaves = jax.tree.leaves(params)
    assert len(specs) == len(leaves) == 39
    for (path, spec), value in zip(specs.items(), leaves):
        assert spec.unit, path
        assert spec.valid[0] <= float(value) <= spec.valid[1], path
        assert spec.valid[0] <= spec.bounds[0] < spec.bounds[1] <= spec.valid[1], path


def test_names_are_tree_paths():
    names = parameter_names(bj.manchester_benchmark())
    assert "primary.kz" in names and "yaw_dampers.c" in names and "masses.frame.mass" in names
    assert len(set(names)) == len(names)


def _primary(**override):
    values = dict(kx=3e7, ky=4e6, kz=1.2e6, cx=15e3, cy=2e3, cz=4e3) | override
    return PrimarySuspension(**values)


@pytest.mark.parametrize(
    "override, pattern",
    [
        ({"kz": -1.0}, r"`PrimarySuspension.kz` = -1.0 N/m is outside its valid range \[0, 1e\+10\] N/m"),
        ({"cy": math.nan}, r"`PrimarySuspension.cy` = nan N s/m is outside its valid range"),
        ({"kx": np.ones(2)}, r"`PrimarySuspension.kx` must be a scalar \[N/m\], got an array of shape \(2,\)"),
    ],
)
def test_invalid_values_name_field_value_and_range(override, pattern):
    with pytest.raises(ParameterError, match=pattern):
        _primary(**override)


def test_non_positive_mass_is_rejected():
    with pytest.raises(ParameterError, match=r"`BodyInertia.mass` = 0.0 kg is outside its valid range \[1, 1e\+06\] kg"):
        BodyInertia(mass=0.0, ixx=1.0, iyy=1.0, izz=1.0)


def test_parameters_are_differentiable_leaves():
    params = bj.manchester_benchmark()
    grad = jax.grad(lambda p: p.primary.kz * 2.0 + p.masses.frame.mass)(params)
    assert float(grad.primary.kz) == 2.0 and float(grad.masses.frame.mass) == 1.0


def test_wheelset_must_be_axisymmetric():
    frame = BodyInertia(mass=2615.0, ixx=1722.0, iyy=1476.0, izz=3067.0)
    wheelset = BodyInertia(mass=1813.0, ixx=1120.0, iyy=112.0, izz=1000.0)
    with pytest.raises(ParameterError, match="must equal `Masses.wheelset.ixx`"):
        bj.params.Masses(frame=frame, wheelset=wheelset, carbody_mass=16000.0)
