"""Coefficients fitted to whole observed trajectories (output error).

:mod:`.solver` is the solver (RK4 with forward sensitivities,
Levenberg-Marquardt with the initial states eliminated, reweighting by a noise
model); :mod:`.noise` the noise models; :mod:`.segments` how records are cut
and grouped for it; :mod:`.terms` the kept terms of a fitted regressor as its
parameters; :mod:`.covariance` the precision of the fit; :mod:`.outliers` the
samples it leaves out; :mod:`.checked` the fit of a regressor accepted only
where held-out data agree, shared by the search's last stage.
"""

from .checked import refine, segment_duration, segmented
from .noise import difference_noise_model
from .segments import group_by_times, growth_rates, shooting_segments, split_times
from .solver import (
    FlowModel,
    TrajectoryFitError,
    fit_initial_states,
    fit_trajectories,
    flow,
)
from .terms import MAX_TERMS, TERMS_PER_STATE, KeptTerms, max_terms

__all__ = [
    "FlowModel",
    "KeptTerms",
    "MAX_TERMS",
    "TERMS_PER_STATE",
    "TrajectoryFitError",
    "difference_noise_model",
    "fit_initial_states",
    "fit_trajectories",
    "flow",
    "group_by_times",
    "growth_rates",
    "max_terms",
    "refine",
    "segment_duration",
    "segmented",
    "shooting_segments",
    "split_times",
]
