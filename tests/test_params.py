"""Parameter modules: units, bounds, named sets and clear errors for invalid values."""

import math

import equinox as eqx
import jax
import numpy as np
import pytest

import bogie_jax as bj
from bogie_jax.params import (
    PARAMETER_SETS,
    BodyInertia,
    ParameterError,
    PrimarySuspension,
    element_names,
    get_parameter,
    parameter_names,
    parameter_specs,
    set_parameters,
)


@pytest.mark.parametrize("name", sorted(PARAMETER_SETS))
def test_named_sets_are_valid_and_inside_their_valid_ranges(name):
    params = PARAMETER_SETS[name]()
    specs = parameter_specs(params)
    leaves = jax.tree.leaves(params)
    assert len(specs) == len(leaves) == 39
    for (path, spec), value in zip(specs.items(), leaves):
        assert spec.unit, path
        assert np.shape(value) == spec.shape, path  # () or one value per element
        lo, hi = spec.valid
        assert np.all((lo <= np.asarray(value)) & (np.asarray(value) <= hi)), path
        assert spec.valid[0] <= spec.bounds[0] < spec.bounds[1] <= spec.valid[1], path
        # the named sets are symmetric: every element of a per-element field has one value
        assert np.all(np.asarray(value) == np.ravel(value)[0]), path


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
        (
            {"kz": -1.0},
            r"`PrimarySuspension.kz` = -1.0 N/m is outside its valid range \[0, 1e\+10\] N/m",
        ),
        ({"cy": math.nan}, r"`PrimarySuspension.cy` = nan N s/m is outside its valid range"),
        (
            {"kx": np.ones(2)},
            r"`PrimarySuspension.kx` must be a scalar \[N/m\], got an array of shape \(2,\)",
        ),
    ],
)
def test_invalid_values_name_field_value_and_range(override, pattern):
    with pytest.raises(ParameterError, match=pattern):
        _primary(**override)


def test_non_positive_mass_is_rejected():
    with pytest.raises(
        ParameterError,
        match=r"`BodyInertia.mass` = 0.0 kg is outside its valid range \[1, 1e\+06\] kg",
    ):
        BodyInertia(mass=0.0, ixx=1.0, iyy=1.0, izz=1.0)


def test_parameters_are_differentiable_leaves():
    params = bj.manchester_benchmark()
    grad = jax.grad(lambda p: p.primary.kz[1] * 2.0 + p.masses.frame.mass)(params)
    assert grad.primary.kz.tolist() == [0.0, 2.0, 0.0, 0.0] and float(grad.masses.frame.mass) == 1.0


def test_wheelset_must_be_axisymmetric():
    frame = BodyInertia(mass=2615.0, ixx=1722.0, iyy=1476.0, izz=3067.0)
    wheelset = BodyInertia(mass=1813.0, ixx=1120.0, iyy=112.0, izz=1000.0)
    with pytest.raises(ParameterError, match="must equal `Masses.wheelset.ixx`"):
        bj.params.Masses(frame=frame, wheelset=wheelset, carbody_mass=16000.0)


# ------------------------------------------------------------------------ per-element fields
def test_per_element_fields_broadcast_scalars_and_keep_arrays():
    p = _primary(kz=[1.0e6, 1.1e6, 1.2e6, 1.3e6])
    assert p.kx.shape == (4,) and np.all(p.kx == 3e7)
    assert p.kz.tolist() == [1.0e6, 1.1e6, 1.2e6, 1.3e6]
    s = bj.params.SecondarySuspension(kx=1.6e5, ky=1.6e5, kz=4.3e5, cy=(32e3, 16e3), cz=2e4)
    assert s.kz.shape == (2,) and s.cy.tolist() == [32e3, 16e3]
    assert bj.params.AXLEBOXES == ("1L", "1R", "2L", "2R") and bj.params.SIDES == ("left", "right")


@pytest.mark.parametrize(
    "override, pattern",
    [
        (
            {"kz": [1e6, 1e6, -1.0, 1e6]},
            r"`PrimarySuspension.kz` = -1.0 N/m at element 2L is outside its valid range",
        ),
        (
            {"kx": np.ones(3)},
            r"must be a scalar \[N/m\], got an array of shape \(3,\) "
            r"\(or one value per element 1L, 1R, 2L, 2R: shape \(4,\)\)",
        ),
    ],
)
def test_invalid_element_values_name_the_element(override, pattern):
    with pytest.raises(ParameterError, match=pattern):
        _primary(**override)


def test_tied_and_element_names():
    params = bj.manchester_benchmark()
    tied = parameter_names(params)
    both = parameter_names(params, elements=True)
    elements = element_names(params)
    assert len(tied) == 39 and len(elements) == 6 * 4 + 5 * 2 + 3 * 2
    assert set(both) == set(tied) | set(elements) and len(both) == len(tied) + len(elements)
    assert both[both.index("primary.kz") + 1 : both.index("primary.kz") + 5] == (
        "primary.1L.kz",
        "primary.1R.kz",
        "primary.2L.kz",
        "primary.2R.kz",
    )
    for name in (
        "secondary.left.cy",
        "secondary.right.kz",
        "yaw_dampers.right.c",
        "yaw_dampers.left.blowoff_velocity",
    ):
        assert name in elements
    specs = parameter_specs(params, elements=True)
    assert specs["primary.2R.cz"] is specs["primary.cz"]


def test_get_and_set_by_element_and_tied_name():
    params = bj.manchester_benchmark()
    p = set_parameters(
        params, {"primary.1L.kz": 1.5e6, "yaw_dampers.left.c": 0.0, "secondary.cy": 40e3}
    )
    assert np.asarray(p.primary.kz).tolist() == [1.5e6, 1.22e6, 1.22e6, 1.22e6]
    assert np.asarray(p.yaw_dampers.c).tolist() == [0.0, 400e3]
    assert np.asarray(p.secondary.cy).tolist() == [40e3, 40e3]
    assert float(get_parameter(p, "primary.1L.kz")) == 1.5e6
    assert float(get_parameter(p, "primary.2R.kz")) == 1.22e6
    assert float(get_parameter(p, "secondary.cy")) == 40e3
    assert float(get_parameter(p, "masses.frame.mass")) == 2615.0
    with pytest.raises(
        ValueError,
        match=r"`primary.kz` has no single value: its elements differ "
        r"\(primary.1L.kz = 1.5e\+06, primary.1R.kz = 1.22e\+06",
    ):
        get_parameter(p, "primary.kz")
    # traced: the mean, exactly the common value for equal elements; differentiable
    assert float(jax.jit(lambda q: get_parameter(q, "primary.kz"))(params)) == 1.22e6
    grad = jax.grad(lambda q: get_parameter(q, "primary.kz"))(params)
    assert np.allclose(grad.primary.kz, 0.25)


@pytest.mark.parametrize(
    "name, pattern",
    [
        (
            "primary.3L.kz",
            r"unknown element '3L' in parameter 'primary.3L.kz': the elements of "
            r"`primary` are 1L, 1R, 2L, 2R",
        ),
        (
            "yaw_dampers.middle.c",
            r"unknown element 'middle' in parameter 'yaw_dampers.middle.c': "
            r"the elements of `yaw_dampers` are left, right",
        ),
        ("secondary.1L.cy", r"the elements of `secondary` are left, right"),
        (
            "primary.kzz",
            r"unknown parameter 'primary.kzz' \(did you mean .*\); valid names: "
            r"masses.frame.mass, .*primary.1L.kx",
        ),
        ("masses.frame.1L.mass", r"unknown parameter 'masses.frame.1L.mass'"),
    ],
)
def test_unknown_names_name_the_value_and_the_choices(name, pattern):
    params = bj.manchester_benchmark()
    with pytest.raises(ValueError, match=pattern):
        get_parameter(params, name)
    with pytest.raises(ValueError, match=pattern):
        set_parameters(params, {name: 1.0})


def test_set_parameters_keeps_numbers_as_array_leaves():
    """A Python number set by name becomes an array leaf, so `eqx.filter_jit` traces a function
    of the parameters once for every value (a float leaf would be static: one trace per value)."""
    traces = []

    @eqx.filter_jit
    def friction(p):
        traces.append(1)
        return p.contact.friction * 2.0

    base = bj.manchester_benchmark()
    for mu in (0.1, 0.2, 0.3):
        p = bj.set_parameters(base, {"contact.friction": mu})
        assert float(friction(p)) == pytest.approx(2 * mu)
    assert len(traces) == 1
