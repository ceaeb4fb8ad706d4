"""Leaving the contact table: an event condition for diffrax (profile contact geometry only).

Beyond its lateral range the table's columns continue linearly (`ProfileGeometry.evaluate`), so
the vector field stays finite, but the motion is then outside the tabulated contact (past flange
climb). `beyond_contact_table` is a `diffrax.Event` condition: a solve that passes
`event=diffrax.Event(beyond_contact_table)` stops there with the status
`diffrax.RESULTS.event_occurred` instead of running on extrapolated geometry.
"""

import jax.numpy as jnp

from ..contact import ProfileGeometry
from . import _kinematics as kin
from ._dynamics import BogieModel, track_inputs


def beyond_contact_table(t, y, model: BogieModel, **kwargs):
    """True when a wheelset's lateral displacement relative to the track, |y_rel|, exceeds the
    contact table's range (always False for the cone, which has no table). Signature of a
    `diffrax.Event` condition `(t, y, args, **kwargs)`."""
    geometry = model.constants.geometry
    if not isinstance(geometry, ProfileGeometry):
        return jnp.asarray(False)
    w, _, _ = track_inputs(model, t)
    y_rel = kin.relative_lateral(y[6:8], w.T, model.params.contact.wheel_radius)
    return jnp.any(jnp.abs(y_rel) > geometry.half_range)
