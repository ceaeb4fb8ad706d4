"""bogie_jax: model-based condition monitoring of railway bogies in JAX."""

import importlib.metadata

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


__version__ = importlib.metadata.version("bogie-jax")
