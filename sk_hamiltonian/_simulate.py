"""A fitted regressor's ``simulate``: the integrator, method and step its fit implies, and the run.

:mod:`._integrate.simulation` checks the arguments, chooses defaults from
plain values and runs the integration; the functions here read those values
from the fitted model (its fit target, training step ``dt_``, time scale
``time_scale_``, and whether a fit on trajectories refined it) and take the
states between the user's column order and the model's. The regressors'
methods ``simulate``, ``_integrator``, ``_default_method`` and
``_default_step`` call them.
"""

from sklearn.utils.validation import check_is_fitted

from ._integrate import make_integrator, simulation


def integrator(model, method=None):
    """The integrator ``method`` (None: the model's default) on the model's dynamics."""
    return make_integrator(default_method(model) if method is None else method,
                           model._dynamics())


def default_method(model):
    """The integrator ``simulate`` uses when ``method`` is None."""
    return simulation.default_method(model._fit_target)


def default_step(model, method):
    """The step ``simulate`` takes with ``method`` when ``max_step`` is None."""
    # A fit on steps learns the AVF map at the data step; coefficients fitted
    # to the trajectories afterwards describe the flow, as any other fit's do.
    refined = getattr(model, "trajectory_fit_status_", None) == "refined"
    return simulation.default_step(
        method, describes_flow=refined or model._fit_target != "steps", dt=model.dt_,
        time_scale=model.time_scale_,
    )


def simulate(model, x0, t, method, max_step, on_failure):
    """The trajectories of ``model.simulate(x0, t, ...)``; see its docstring."""
    check_is_fitted(model)
    x0, single = simulation.check_initial_states(x0, model.n_features_in_)
    x0 = model._to_model(x0)
    t = simulation.check_time(t)
    simulation.check_max_step(max_step)
    simulation.check_outputs(t.shape[0], x0.shape[0], model.n_features_in_)
    chosen = integrator(model, method)
    default = None
    if max_step is None:
        max_step = default_step(model, chosen.name)
        default = "the default step for this model"
    simulation.check_steps(t, max_step, default)
    simulation.check_on_failure(on_failure)
    simulation.warn_slow_avf(chosen.name, t, max_step)
    Y, reached = simulation.run(chosen, x0, t, max_step, on_failure,
                                what=f"the learned system ({type(model).__name__})")
    # Levels from _warn_outside (1): here (2), simulate (3), its caller (4).
    model._warn_outside(Y[reached], what="the simulated states", stacklevel=4)
    Y = model._to_model(Y)  # back to the user's column order
    return Y[0] if single else Y
