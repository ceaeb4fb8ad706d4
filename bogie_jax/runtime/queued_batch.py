"""A batch of iterative members run as a queue: a lane whose member has finished takes the next.

`batch_runner` vmaps whole members, so a vmapped `while_loop` steps every member of a chunk until
the slowest one is done: one multistart fit that runs to its step limit makes the whole chunk
wait (lock-step). Here each device holds a few *lanes*; every iteration advances all lanes by one
step of their member, and a lane whose member has finished writes its output and starts the next
member of its device's queue. The batch then costs about the sum of its members' steps divided
by the lanes, plus one tail; members need not take equal numbers of steps. A device with one
lane steps its member without `vmap` (a smaller program, and no batched branches or loops).

A member is an `IterativeMember`: `init(x) -> carry`, `step(carry) -> carry`,
`done(carry) -> bool` and `output(carry) -> pytree`. The members are split over the devices in
contiguous blocks and each device runs the queue of its block on its own (`batch.per_device`,
`jax.shard_map`: no device waits for another; a member must not call lineax's own solvers, see
there); the outputs come back in input order with per-member failure flags as in `batch_runner`.
"""

import math
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.sharding import PartitionSpec

from .batch import BatchResult, BatchRunner, _batch_size, _pad, member_failed, per_device


class IterativeMember(eqx.Module):
    """One member as an iteration (all four functions jit/vmap-safe, `carry` a pytree of arrays).

    - `init(x)`: the carry of a new member from its input `x` (called for every refill, so it
      should be cheap: no simulation). A member is stepped at least once, even if `done` holds
      for its initial carry.
    - `step(carry)`: one iteration.
    - `done(carry)`: whether the member has finished (converged, failed or out of steps).
    - `output(carry)`: the member's result.
    """

    init: Callable
    step: Callable
    done: Callable
    output: Callable


def _where(pred, new, old):
    """Select per lane (`pred` of shape `(lanes,)`) between two carries."""

    def pick(a, b):
        p = jnp.reshape(pred, pred.shape + (1,) * (jnp.ndim(a) - 1))
        return jnp.where(p, a, b)

    return jax.tree.map(pick, new, old)


def _one_lane(fn):
    """`jax.vmap(fn)` for a leading axis of size 1, without batching `fn`'s trace."""
    return lambda x: jax.tree.map(lambda a: a[None], fn(jax.tree.map(lambda a: a[0], x)))


def _device_queue(member: IterativeMember, lanes: int, post: Callable | None):
    """`items -> outputs` for one device's queue (leading axis = member)."""

    def run(items):
        m = _batch_size(items)
        k = min(lanes, m)
        take = lambda idx: jax.tree.map(lambda x: x[idx], items)
        lanes_map = jax.vmap if k > 1 else _one_lane
        init = lanes_map(member.init)
        carry = init(take(jnp.arange(k)))
        out_shape = jax.eval_shape(member.output, jax.tree.map(lambda x: x[0], carry))
        outputs = jax.tree.map(lambda s: jnp.zeros((m, *s.shape), s.dtype), out_shape)

        def cond(state):
            _, index, _, _ = state
            return jnp.any(index < m)

        def body(state):
            carry, index, next_index, outputs = state
            active = index < m
            # an idle lane (its queue is empty) is stepped with the others but stays frozen, as a
            # finished member of a vmapped while_loop does (it re-evaluates its last point rather
            # than iterating on past its end)
            carry = _where(active, lanes_map(member.step)(carry), carry)
            finished = lanes_map(member.done)(carry) & active
            # write finished members (index m is out of range and dropped)
            where = jnp.where(finished, index, m)
            outputs = jax.tree.map(
                lambda o, v: o.at[where].set(v, mode="drop"),
                outputs,
                lanes_map(member.output)(carry),
            )
            new_index = jnp.where(finished, next_index + jnp.cumsum(finished) - 1, index)
            next_index = next_index + jnp.sum(finished)
            refill = finished & (new_index < m)
            fresh = init(take(jnp.clip(new_index, 0, m - 1)))
            index = jnp.where(finished & ~refill, m, new_index)
            return _where(refill, fresh, carry), index, next_index, outputs

        state = (carry, jnp.arange(k), jnp.asarray(k), outputs)
        outputs = jax.lax.while_loop(cond, body, state)[3]
        return outputs if post is None else jax.vmap(post)(items, outputs)

    return run


def queued_runner(
    member: IterativeMember,
    *,
    lanes: int = 1,
    devices=None,
    post: Callable | None = None,
    failure_fn: Callable | None = None,
) -> BatchRunner:
    """Compile an iterative `member` into a `bogie_jax.runtime.batch.BatchRunner`:
    `run(batch) -> BatchResult` (as `batch_runner`).

    **Arguments:**
    - `member`: an `IterativeMember`.
    - `lanes`: members in flight per device (vmapped together; bounds memory).
    - `devices`: devices to shard the queue over (default `jax.devices()`).
    - `post`: optional `(x, output) -> result` applied to every member after the queue, as one
      vmapped batch (e.g. the cost at a fit's end).
    - `failure_fn`: optional `result -> bool` marking failed members; non-finite results are
      always failed.

    `run.compile(batch)` compiles for batches of that shape ahead of time, without running.
    """
    if int(lanes) < 1:
        raise ValueError(f"`lanes` must be >= 1, got {lanes}")
    devices = list(devices) if devices is not None else jax.devices()
    n_dev = len(devices)
    queue = _device_queue(member, int(lanes), post)

    def flagged(items):
        out = queue(items)
        return out, jax.vmap(lambda o: member_failed(o, failure_fn))(out)

    # each device runs the queue of its contiguous block of members
    sharded, sharding = per_device(flagged, devices, PartitionSpec("batch"))

    def prepare(batch):
        n = _batch_size(batch)
        padded = _pad(batch, math.ceil(n / n_dev) * n_dev)
        return jax.device_put(padded, sharding), n

    def finish(outputs, n) -> BatchResult:
        out, failed = outputs
        head = lambda x: x[:n]
        return BatchResult(outputs=jax.tree.map(head, out), failed=head(failed))

    return BatchRunner(sharded, prepare, finish)
