"""How the package's programs run: solve settings, batch runners, the persistent caches.

- `solve_settings`: `SolveSettings`, the one module of diffrax solve options.
- `batch`: `batch_runner`, vmap in chunks sharded over devices, failed members reported;
  `per_device_runner`, each device's block of members run on its own.
- `program_store`: batch programs kept across processes (`jax.export`).
- `compilation_cache`: `use_compilation_cache`, JAX's persistent cache and the store beside it.
- `cores`: `available_cores`, `core_count`, the CPU cores this process may run on.

The modules are imported by name (`bogie_jax.runtime.batch`); this package imports none of them,
so that the command line can import `compilation_cache` before JAX is loaded.
"""
