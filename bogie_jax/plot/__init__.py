"""Matplotlib figures, one module per family: a run (trajectory, stability), gradient checks,
identification and sensitivity, cost contours, Sobol against Fisher rankings, the
convergence of identification runs, and condition monitoring (verdicts against bands, measured
against fitted signals, trends). matplotlib is imported when a figure is drawn; nothing in the
core imports this package. Every function taking `ax=None` draws on a new figure otherwise."""

from ._convergence import plot_convergence as plot_convergence, plot_runs as plot_runs
from ._gradients import (
    plot_gradient_components as plot_gradient_components,
    plot_gradient_cost as plot_gradient_cost,
)
from ._identify import plot_estimates as plot_estimates, plot_waterfall as plot_waterfall
from ._monitor import (
    plot_signal_fit as plot_signal_fit,
    plot_trend as plot_trend,
    plot_verdicts as plot_verdicts,
)
from ._ranking import plot_sensitivity_ranking as plot_sensitivity_ranking
from ._sensitivity import (
    plot_cost_surface as plot_cost_surface,
    plot_fim_eigenvalues as plot_fim_eigenvalues,
    plot_profiles as plot_profiles,
    plot_sobol_indices as plot_sobol_indices,
    plot_sweeps as plot_sweeps,
)
from ._surface import plot_cost_contour as plot_cost_contour
from ._trajectory import plot_simulation as plot_simulation, plot_stability as plot_stability
