"""bogie_jax: model-based condition monitoring of railway bogies in JAX.

The re-exports below load on first use (PEP 562), so `import bogie_jax` imports no JAX: the
command line (`bogie_jax.cli.main`) must set `XLA_FLAGS` before JAX is imported.
"""

import importlib
import importlib.metadata
from typing import TYPE_CHECKING


if TYPE_CHECKING:
    from .cost import (
        Objective as Objective,
        ParameterSelection as ParameterSelection,
        make_objective as make_objective,
        select_parameters as select_parameters,
    )
    from .gradients import gradient as gradient, scalar_product_test as scalar_product_test
    from .measure import (
        Measurement as Measurement,
        default_sensor_layout as default_sensor_layout,
        synthetic_measurement as synthetic_measurement,
    )
    from .params import (
        BogieParams as BogieParams,
        ModelOptions as ModelOptions,
        ParameterError as ParameterError,
        crh380a as crh380a,
        manchester_benchmark as manchester_benchmark,
    )

_EXPORTS = {
    "cost": ("Objective", "ParameterSelection", "make_objective", "select_parameters"),
    "gradients": ("gradient", "scalar_product_test"),
    "measure": ("Measurement", "default_sensor_layout", "synthetic_measurement"),
    "params": ("BogieParams", "ModelOptions", "ParameterError", "crh380a", "manchester_benchmark"),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}
__all__ = sorted(_WHERE)

__version__ = importlib.metadata.version("bogie-jax")


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
        globals()[name] = value  # later look-ups skip this function
        return value
    raise AttributeError(f"module 'bogie_jax' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_WHERE])
