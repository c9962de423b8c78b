"""Words shared by the command's lines: counted nouns ("1 candidate"), the friction."""


def counted(n, singular, plural=None):
    """``n`` and the noun that agrees with it (``plural`` defaults to ``singular + "s"``)."""
    return f"{n} {singular if n == 1 else (plural or singular + 's')}"


def friction_line(model, names):
    """``friction: gamma_p = 0.3 (dp/dt = -dH/dq - gamma dH/dp)``, or None without damping.

    The fit's report and ``show`` say the friction in the same words, by the
    momenta's names, rather than as the attribute ``damping_`` alone.
    """
    if not getattr(model, "damping", False) or getattr(model, "damping_", None) is None:
        return None
    d = len(model.damping_)
    return ("friction: " + ", ".join(
        f"gamma_{name} = {value:.4g}" for name, value in zip(names[:d], model.damping_))
        + " (dp/dt = -dH/dq - gamma dH/dp)")
