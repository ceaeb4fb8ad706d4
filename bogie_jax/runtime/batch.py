"""One batch runner for every batched workload (multistart fits, screening, Sobol, speed sweeps).

`batch_runner(fn)` returns a compiled function that evaluates `fn` over the leading axis of a
pytree batch: `vmap` over chunks of `chunk_size` members, `lax.map` over the chunks (bounded
memory), and the members of each chunk spread over the devices by `jax.sharding` (on a CPU,
expose several host devices with `XLA_FLAGS=--xla_force_host_platform_device_count=N` before
importing JAX). `per_device_runner` runs each device's block on its own (`per_device`,
`jax.shard_map`): a batch whose width is the work in flight, e.g. one evaluation per fit.
A member whose output is non-finite, or flagged by `failure_fn`, is reported in
`BatchResult.failed`; nothing raises because of one member (use `throw=False` in solves).
"""

import math
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import PartitionSpec

from .program_store import stored_program


class BatchResult(eqx.Module):
    """Outputs of a batch (leading axis = member) and a per-member failure flag."""

    outputs: object
    failed: jax.Array


def _all_finite(tree):
    leaves = [x for x in jax.tree.leaves(tree) if jnp.issubdtype(jnp.asarray(x).dtype, jnp.inexact)]
    if not leaves:
        return jnp.asarray(True)
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(x)) for x in leaves]))


def _batch_size(batch) -> int:
    sizes = {np.shape(x)[0] for x in jax.tree.leaves(batch)}
    if len(sizes) != 1:
        raise ValueError(
            f"`batch` leaves must share one leading (member) axis, got sizes {sorted(sizes)}"
        )
    return sizes.pop()


def _pad(batch, total: int):
    def pad_leaf(x):
        x = jnp.asarray(x)
        extra = total - x.shape[0]
        if extra == 0:
            return x
        return jnp.concatenate([x, jnp.repeat(x[-1:], extra, axis=0)])

    return jax.tree.map(pad_leaf, batch)


def member_failed(out, failure_fn: Callable | None = None) -> jax.Array:
    """Whether one member's output is non-finite or flagged by `failure_fn`."""
    failed = jnp.logical_not(_all_finite(out))
    if failure_fn is not None:
        failed = failed | jnp.asarray(failure_fn(out))
    return failed


def per_device(fn: Callable, devices, spec: PartitionSpec):
    """`jit` of `fn` run on each device's block of the member axis on its own (`shard_map`).

    Not a sharded `jit` of the whole batch (GSPMD): there, a vmapped `while_loop` (every ODE
    solve, every fit) ends when the members of *all* devices are done, so every iteration
    synchronises the devices, and a second device buys next to nothing. Each device's block runs
    its own loops here.
    `check_vma=False` because `fn` uses no collectives and optimistix's Jacobian products
    do not type-check under the varying-manual-axes check (jax 0.10.2). `fn` must not call
    lineax's own solvers, which reject right-hand sides inside `shard_map` (see `batch_runner`);
    the library's `HouseholderQR` (the static equilibrium's solves) works.
    """
    mesh = jax.sharding.Mesh(np.array(list(devices)), ("batch",))
    sharding = jax.sharding.NamedSharding(mesh, spec)
    mapped = jax.shard_map(fn, mesh=mesh, in_specs=spec, out_specs=spec, check_vma=False)
    return jax.jit(mapped, in_shardings=sharding, out_shardings=sharding), sharding


class BatchRunner:
    """A compiled batch: `run(batch) -> BatchResult` (what `batch_runner` and
    `per_device_runner` return).

    - `run(batch)`: run the batch (compiled on the first call for its signature: structure,
      shapes and dtypes of the batch's leaves).
    - `run.compile(batch)`: compile for batches of that signature ahead of time, without running.
    - `run.program(batch)`: `(jitted, args)`, the jitted program and the batch prepared for it
      (padded, laid out and placed on the devices): `jitted(*args)` runs it, `jitted.lower(*args)`
      lowers it (for inspection, e.g. the compile benchmark).

    The programs are kept by JAX's own caches of the jitted function (trace, lowering,
    compilation), not here: a call after `compile` runs the program compiled ahead. With an
    `identity` (a picklable description of everything the program closes over) and the program
    store on (`bogie_jax.runtime.program_store`), the traced program is also kept across processes.
    """

    def __init__(self, jitted: Callable, prepare: Callable, finish: Callable, identity=None):
        self._jitted = jitted  # jax.jit of the whole (sharded) batch
        self._prepare = prepare  # batch -> (device args, layout)
        self._finish = finish  # (program outputs, layout) -> BatchResult
        self.identity = identity

    def with_identity(self, identity) -> "BatchRunner":
        """This runner, its program stored under `identity` where the store is on."""
        return BatchRunner(self._jitted, self._prepare, self._finish, identity)

    def program(self, batch) -> tuple[Callable, tuple]:
        return self._jitted, (self._prepare(batch)[0],)

    def _runnable(self, args: tuple):
        """`(program, its arguments, output rebuild)`: the stored program on the flat leaves of
        `args` where the store has it, else the jitted program on `args`."""
        stored = stored_program(self._jitted, args, self.identity)
        if stored is None:
            return self._jitted, args, lambda out: out
        call, out_tree = stored
        return call, tuple(jax.tree.leaves(args)), lambda out: jax.tree.unflatten(out_tree, out)

    def compile(self, batch) -> None:
        """Compile for batches shaped like `batch` without running (kept for later runs)."""
        program, args, _ = self._runnable((self._prepare(batch)[0],))
        program.lower(*args).compile()

    def __call__(self, batch) -> BatchResult:
        device_args, layout = self._prepare(batch)
        program, args, rebuild = self._runnable((device_args,))
        return self._finish(rebuild(program(*args)), layout)


def batch_runner(
    fn: Callable,
    *,
    chunk_size: int | None = None,
    devices=None,
    failure_fn: Callable | None = None,
) -> BatchRunner:
    """Compile `fn` (one member -> pytree) into a `BatchRunner`: `run(batch) -> BatchResult`.

    **Arguments:**
    - `fn`: pure function of one member of the batch.
    - `chunk_size`: members evaluated together by `vmap` on one device (default: all of the
      device's share in one chunk).
    - `devices`: devices to shard over (default `jax.devices()`).
    - `failure_fn`: optional `output -> bool` marking failed members (e.g. a solver status).

    `run.compile(batch)` compiles for batches of that shape ahead of time, without running.
    """
    devices = list(devices) if devices is not None else jax.devices()
    n_dev = len(devices)

    def member(x):
        out = fn(x)
        failed = member_failed(out, failure_fn)
        return out, failed

    def local(chunked):
        return jax.lax.map(jax.vmap(member), chunked)

    # The member axis of the jitted batch is sharded over the devices (GSPMD), not split by
    # `per_device`: inside `shard_map`, lineax's own solvers (e.g. the QR of optimistix's
    # default LM) reject their right-hand sides, whose types carry the mesh differently from
    # the operator's (jax 0.10.2). The price: a vmapped `while_loop` waits for every device.
    mesh = jax.sharding.Mesh(np.array(devices), ("batch",))
    sharding = jax.sharding.NamedSharding(mesh, PartitionSpec(None, "batch"))
    sharded = jax.jit(local, in_shardings=sharding, out_shardings=sharding)

    def prepare(batch):
        n = _batch_size(batch)
        per_device = math.ceil(n / n_dev)
        chunk = min(chunk_size or per_device, per_device)
        n_chunks = math.ceil(per_device / chunk)
        total = n_chunks * chunk * n_dev
        padded = _pad(batch, total)
        # (n_chunks, n_dev * chunk, ...): chunk k of every device sits in row k.
        chunked = jax.tree.map(
            lambda x: (
                x.reshape(n_dev, n_chunks, chunk, *x.shape[1:])
                .swapaxes(0, 1)
                .reshape(n_chunks, n_dev * chunk, *x.shape[1:])
            ),
            padded,
        )
        return jax.device_put(chunked, sharding), (n, n_chunks, chunk, total)

    def finish(outputs, layout) -> BatchResult:
        out, failed = outputs
        n, n_chunks, chunk, total = layout

        def unchunk(x):
            x = x.reshape(n_chunks, n_dev, chunk, *x.shape[2:]).swapaxes(0, 1)
            return x.reshape(total, *x.shape[3:])[:n]

        return BatchResult(outputs=jax.tree.map(unchunk, out), failed=unchunk(failed))

    return BatchRunner(sharded, prepare, finish)


def _block(fn: Callable):
    """`fn` over a block of members: `vmap`, except for a block of one member, which runs
    unbatched (a smaller program: a batched `cond` evaluates both branches)."""

    def run(block):
        if _batch_size(block) == 1:
            return jax.tree.map(lambda a: a[None], fn(jax.tree.map(lambda a: a[0], block)))
        return jax.vmap(fn)(block)

    return run


def per_device_runner(
    fn: Callable, *, devices=None, failure_fn: Callable | None = None
) -> BatchRunner:
    """Compile `fn` (one member -> pytree) into a `BatchRunner` whose members are split over
    the devices in contiguous blocks, each device's block run on its own (`per_device`: no
    device waits for another's loops) and vmapped (`_block`). For a batch whose width is the
    work in flight, e.g. one residual-Jacobian evaluation of every fit of a
    `bogie_jax.identify` queue per iteration: a leaf of the batch already placed as this runner
    places it (padded to a multiple of the devices, sharded over them) is not placed again.
    `fn` must not call lineax's own solvers (see `per_device`). `devices`, `failure_fn`: as in
    `batch_runner`."""
    devices = list(devices) if devices is not None else jax.devices()
    n_dev = len(devices)
    block = _block(fn)

    def flagged(items):
        out = block(items)
        return out, jax.vmap(lambda o: member_failed(o, failure_fn))(out)

    sharded, sharding = per_device(flagged, devices, PartitionSpec("batch"))

    def prepare(batch):
        n = _batch_size(batch)
        total = math.ceil(n / n_dev) * n_dev

        def place(x):  # a leaf already laid out for this runner stays where it is
            if isinstance(x, jax.Array) and x.shape[0] == total and x.sharding == sharding:
                return x
            return jax.device_put(_pad(x, total), sharding)

        return jax.tree.map(place, batch), n

    def finish(outputs, n) -> BatchResult:
        out, failed = outputs
        head = lambda x: x[:n]
        return BatchResult(outputs=jax.tree.map(head, out), failed=head(failed))

    return BatchRunner(sharded, prepare, finish)
