"""The noise model of a fit on the host: a sensor bias removed and each channel's noise level
estimated (numpy on the residuals r and Jacobian J of a compiled program), for `monitor` and
`bogie_jax.identify` alike.

**Sensor bias** (a constant per run and channel the fit is not told): a linear nuisance
parameter b_kc, eliminated by variable projection (Golub & Pereyra, SIAM J. Numer. Anal. 10
(1973) 413-432): for fixed suspension parameters the best bias is the mean residual of the
run-channel over its present samples, so the fit minimises |P r|^2 with P the projection that
centres every run-channel's residuals over time; since P does not depend on the parameters,
P J is the exact Jacobian of P r. The estimates equal those of a fit with explicit bias
parameters (tests/test_monitor_robust.py checks it against `numpy.linalg.lstsq` with bias
columns); one degree of freedom is used per run and channel.

**Per-channel noise** (each channel's noise level unknown): after a fit, the residual variance
of run-channel kc in units of the assumed noise variance (the sensors' `noise_std`) is

    s2_kc = |r_kc|^2 / (n_kc - b - h_kc),

n_kc its present samples, b = 1 if the bias is removed, h_kc = sum over its rows of the
leverage diag(J H^+ J^T) of the weighted Jacobian (the share of the fitted parameters' degrees
of freedom that falls on the channel: the sum of h_kc over all channels is the rank of J).
The rows are then weighted by 1 / sqrt(max(s2_kc, floor)) (feasible weighted least squares,
e.g. Carroll & Ruppert, "Transformation and Weighting in Regression", 1988, ch. 2; the floor,
1e-4 of the assumed variance, keeps a channel that the model fits perfectly from dominating),
normalised so that the pooled variance of the weighted residuals stays that of the first fit
(only the relative weights change; the scale, s2, is estimated with the covariance).
"""

import dataclasses

import numpy as np


S2_FLOOR = 1e-4


@dataclasses.dataclass(frozen=True)
class RunChannels:
    """The layout of the residual vector of a joint objective: run k's rows `slices[k]` are
    sample-major `(n_times_k, n_channels)`; `mask` (m,) True where a sample is present (missing
    samples have exactly zero residual and Jacobian rows); `active` (n_runs,) the runs used.

    Build it with `RunChannels.of(slices, n_channels, mask, active)`.
    """

    slices: tuple
    n_channels: int
    mask: np.ndarray
    active: np.ndarray

    @classmethod
    def of(cls, slices, n_channels, mask=None, active=None) -> "RunChannels":
        slices = tuple(slices)
        m = max((sl.stop for sl in slices), default=0)
        mask = np.ones(m, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        active = np.ones(len(slices), bool) if active is None else np.asarray(active, bool)
        if int(n_channels) < 1:
            raise ValueError(f"`n_channels` = {n_channels!r} must be >= 1")
        if mask.shape != (m,):
            raise ValueError(f"`mask` must have shape ({m},), got {mask.shape}")
        if active.shape != (len(slices),):
            raise ValueError(f"`active` must have shape ({len(slices)},), got {active.shape}")
        for k, sl in enumerate(slices):
            if (sl.stop - sl.start) % int(n_channels):
                raise ValueError(
                    f"run {k} has {sl.stop - sl.start} rows, not a whole number of samples of "
                    f"{n_channels} channels"
                )
        return cls(slices, int(n_channels), mask, active)

    @property
    def n_runs(self) -> int:
        return len(self.slices)

    def _block(self, x, k):
        """Run k's rows of x as (n_times, n_channels, ...)."""
        return x[self.slices[k]].reshape(-1, self.n_channels, *x.shape[1:])

    def counts(self) -> np.ndarray:
        """(n_runs, n_channels) present samples of each active run-channel (0 if inactive)."""
        out = np.zeros((self.n_runs, self.n_channels), dtype=int)
        for k in range(self.n_runs):
            if self.active[k]:
                out[k] = self._block(self.mask, k).sum(axis=0)
        return out

    @property
    def n_present(self) -> int:
        """Present residuals of the active runs."""
        return int(self.counts().sum())

    @property
    def n_bias(self) -> int:
        """Bias parameters: one per active run-channel with a present sample."""
        return int(np.count_nonzero(self.counts()))

    def centre(self, x) -> np.ndarray:
        """x (m,) or (m, n) with every run-channel's mean over its present samples removed
        (the bias projection P); missing rows stay exactly zero. A run-channel holding a
        non-finite value (a rejected step's infinite residuals) comes out non-finite, silently."""
        x = np.array(x, dtype=float, copy=True)
        with np.errstate(invalid="ignore"):  # inf - inf: the non-finite stays non-finite
            for k, sl in enumerate(self.slices):
                block = self._block(x, k)
                mask = self._block(self.mask, k)
                mask = mask.reshape(mask.shape + (1,) * (block.ndim - 2))
                count = np.maximum(mask.sum(axis=0), 1)
                mean = np.where(mask, block, 0.0).sum(axis=0) / count
                x[sl] = (block - np.where(mask, mean, 0.0)).reshape(x[sl].shape)
        return x

    def expand(self, values) -> np.ndarray:
        """(m,) rows from per run-channel `values` (n_runs, n_channels)."""
        values = np.asarray(values, dtype=float)
        out = np.empty(self.mask.shape)
        for k, sl in enumerate(self.slices):
            n_times = (sl.stop - sl.start) // self.n_channels
            out[sl] = np.tile(values[k], n_times)
        return out

    def sum_squares(self, x) -> np.ndarray:
        """(n_runs, n_channels) sums of x^2 (x (m,)) per run-channel."""
        return np.stack([np.sum(self._block(x, k) ** 2, axis=0) for k in range(self.n_runs)])


def leverage(jac, rcond: float = 1e-12) -> np.ndarray:
    """(m,) diag(J H^+ J^T), H = J^T J: each row's share of the fitted parameters (sums to the
    rank of J), from the SVD J = U S V^T as the row sums of U^2 over the kept singular values."""
    jac = np.asarray(jac, dtype=float)
    if jac.shape[1] == 0:
        return np.zeros(jac.shape[0])
    u, s, _ = np.linalg.svd(jac, full_matrices=False)
    keep = s**2 > rcond * np.max(s**2) if np.max(s) > 0 else np.zeros(s.shape, bool)
    return np.sum(u[:, keep] ** 2, axis=1)


def channel_variances(r, jac, layout: RunChannels, *, remove_bias: bool = True, weights=None):
    """(n_runs, n_channels) residual variance s2_kc of every run-channel in units of the
    assumed noise variance (module docstring), NaN for inactive runs or channels without
    degrees of freedom.

    `r`, `jac`: the (weighted, and centred if `remove_bias`) residuals and Jacobian of the fit;
    `weights`: the (n_runs, n_channels) row weights they carry (1 / sqrt of the variances used;
    default 1), divided out of `r` here.
    """
    r = np.asarray(r, dtype=float)
    w = np.ones((layout.n_runs, layout.n_channels)) if weights is None else np.asarray(weights)
    lev = leverage(jac)
    h = np.stack([layout._block(lev, k).sum(axis=0) for k in range(layout.n_runs)])
    dof = layout.counts() - (1 if remove_bias else 0) - h
    ss = layout.sum_squares(r) / w**2
    ok = (dof > 0.5) & layout.active[:, None]
    return np.where(ok, ss / np.where(ok, dof, 1.0), np.nan)


def channel_weights(s2, *, floor: float = S2_FLOOR, reference: float | None = None):
    """(n_runs, n_channels) row weights 1 / sqrt(max(s2_kc, floor)), times sqrt(reference) so
    that only relative weights change (module docstring); run-channels without an estimate
    (NaN) get the median weight of the others."""
    s2 = np.asarray(s2, dtype=float)
    finite = np.isfinite(s2)
    if not finite.any():
        return np.ones_like(s2)
    clipped = np.where(finite, np.maximum(s2, floor), np.nan)
    w = 1.0 / np.sqrt(clipped)
    w = np.where(finite, w, np.median(w[finite]))
    ref = 1.0 if reference is None else max(float(reference), floor)
    return w * np.sqrt(ref)
