"""bogie_jax: model-based condition monitoring of railway bogies in JAX."""

import importlib.metadata

from .params import (
    BogieParams as BogieParams,
    ModelOptions as ModelOptions,
    ParameterError as ParameterError,
    crh380a as crh380a,
    manchester_benchmark as manchester_benchmark,
)


__version__ = importlib.metadata.version("bogie-jax")
