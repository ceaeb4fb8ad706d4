"""bogie_jax: model-based condition monitoring of railway bogies in JAX.

The re-exports below load on first use (PEP 562), so `import bogie_jax` imports no JAX: the
command line (`bogie_jax.cli.main`) must set `XLA_FLAGS` before JAX is imported.
"""

import importlib

from . import _version


_EXPORTS = {  # what a notebook needs, by module
    "params": (
        "BogieParams",
        "ModelOptions",
        "ParameterError",
        "crh380a",
        "element_names",
        "get_parameter",
        "manchester_benchmark",
        "parameter_names",
        "set_parameters",
    ),
    "track": ("TrackReference", "perfect_track", "synthesise_track"),
    "model": ("critical_speed", "stability_sweep", "static_equilibrium"),
    "simulation": ("SolveSettings", "Trajectory", "simulate"),
    "measure": ("Measurement", "default_sensor_layout", "synthetic_measurement"),
    "cost": ("Objective", "ParameterSelection", "make_objective", "select_parameters"),
    "gradients": ("gradient", "scalar_product_test"),
    "identify": (
        "fit",
        "fit_hybrid",
        "fit_multistart",
        "fit_multistart_chunked",
        "scenario_problem",
        "simulated_annealing",
    ),
    "sensitivity": ("fisher_information", "profile_likelihood", "sensitivity_sobol"),
    "runtime.compilation_cache": ("use_compilation_cache",),
    "monitor": (  # the subpackage: `bogie_jax.monitor.monitor` is the function
        "DEFECT_SCENARIOS",
        "DefectScenario",
        "MonitorOptions",
        "RunSpec",
        "ToleranceBand",
        "judge",
        "scenario_measurements",
        "trend",
    ),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}
__all__ = sorted(_WHERE)
__version__ = _version.VERSION


def __getattr__(name: str):
    if name in _EXPORTS:  # a subpackage, e.g. `bogie_jax.params`
        return importlib.import_module(f".{name}", __name__)
    if name in _WHERE:
        value = getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
        globals()[name] = value  # later look-ups skip this function
        return value
    raise AttributeError(f"module 'bogie_jax' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_WHERE])
