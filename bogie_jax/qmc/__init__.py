"""Quasi-Monte Carlo points: the (scrambled) Sobol' sequence."""

from ._sobol import MAX_DIMENSION as MAX_DIMENSION, sobol_sequence as sobol_sequence
