"""Warnings that point at the user's line, however deep in the package they are raised.

A fixed ``stacklevel`` counts frames, and the count changes with every
helper, with scikit-learn's ``_fit_context`` wrapper, and with the path a
call took (``fit`` or ``partial_fit``, a Pipeline, a search): a warning
then names ``sklearn/base.py`` or ``sys:1``. :func:`warn` walks up the stack
instead, to the first frame outside this package, scikit-learn and joblib,
which is where the user called the public method (their own ``fit``, or the
``Pipeline.fit`` or ``GridSearchCV.fit`` that called it).
"""

import os
import sys
import warnings

import joblib
import sklearn

_INTERNAL = tuple(
    os.path.dirname(os.path.abspath(module.__file__)) + os.sep
    for module in (sys.modules[__package__], sklearn, joblib)
)


def _is_internal(filename):
    return os.path.abspath(filename).startswith(_INTERNAL)


def user_stacklevel():
    """The ``stacklevel`` of ``warnings.warn`` that names the caller's first frame outside the package.

    For ``warnings.warn`` called by the function that calls this one.
    """
    # Level 1 is the function calling warnings.warn (this function's caller).
    frame, level = sys._getframe(1), 1
    while frame is not None and _is_internal(frame.f_code.co_filename):
        frame, level = frame.f_back, level + 1
    return level


def warn(message, category):
    """``warnings.warn(message, category)`` attributed to the user's line.

    Parameters
    ----------
    message : str or Warning
        The message, or a warning instance (which carries its own category).
    category : type
        The warning class.
    """
    # user_stacklevel counts from this function's frame, as warnings.warn does here.
    warnings.warn(message, category, stacklevel=user_stacklevel())
