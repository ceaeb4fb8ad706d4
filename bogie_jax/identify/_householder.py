"""The identification layer's least-squares step solver (defined in `bogie_jax._householder`)."""

from .._householder import HouseholderQR as HouseholderQR
