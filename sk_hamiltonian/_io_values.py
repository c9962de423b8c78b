"""How values go into a model file's JSON manifest, and come back exactly.

A value is written as one of these forms, and nothing else can be read:

* ``null``, ``true``/``false``, an integer, a float, a string: itself (Python
  ``None``, ``bool``, ``int``, ``float``, ``str``);
* ``{"float": "nan" | "inf" | "-inf"}``: a non-finite Python float (JSON has none);
* ``{"scalar": v, "dtype": "<i8"}``: a numpy scalar of that dtype (``v`` a
  number, a boolean, a string for ``numpy.str_``, or for a float one of the
  three strings above);
* ``{"items": [...], "as": "list" | "tuple" | "object"}``: a list, a tuple or a
  1-D object array, item by item (so ``[(0, 1), (2, 3)]`` stays a list of
  tuples and ``[[-1, 1.5]]`` keeps its ``int``);
* ``{"array": "arrays/0003.npy", "shape": [...], "dtype": "<f8", "as": "ndarray"}``:
  a numeric array, stored as an ``.npy`` member.

Format 1 also wrote lists and tuples as arrays (``"as": "list"``) and lists
of strings as ``{"strings": [...], "as": ...}``; those still load.
"""

import math
import re
from numbers import Integral, Real

import numpy as np

from ._io_zip import ARRAY_KINDS, ModelFileError

SPECIAL_FLOATS = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}
#: Deepest nesting of lists and tuples (``domain`` as a list of lists is 2).
MAX_DEPTH = 4
#: A dtype as the manifest writes it: byte order, kind, item size (``"<f8"``, ``"|b1"``).
DTYPE_TEXT = re.compile(r"\A[<>|=](?:[biuf][1-9][0-9]?|U[0-9]{1,4})\Z")
#: Numpy scalar types a file may hold (kind: booleans, integers, floats, strings).
SCALAR_KINDS = "biufU"
REFERENCE_KEYS = {"array", "shape", "dtype", "as"}


def _special(value):
    """The text of a non-finite float, or the float itself."""
    if math.isfinite(value):
        return value
    return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")


class Encoder:
    """Encodes values for the manifest and collects the arrays it refers to."""

    def __init__(self):
        self.arrays = {}

    def encode(self, value, what):
        """A JSON-able form of ``value`` (``what`` names it in errors)."""
        if value is None or type(value) in (bool, str, int):
            return value
        if type(value) is float:
            return value if math.isfinite(value) else {"float": _special(value)}
        if isinstance(value, np.generic):
            return self._scalar(value, what)
        if isinstance(value, (list, tuple)):
            kind = "list" if isinstance(value, list) else "tuple"
            return {"items": [self.encode(v, what) for v in value], "as": kind}
        if isinstance(value, np.ndarray):
            return self._array(value, what)
        if isinstance(value, str):  # a str subclass
            return str(value)
        if isinstance(value, Integral):
            return int(value)
        if isinstance(value, Real):
            return self.encode(float(value), what)
        raise TypeError(
            f"cannot save {what}: a value of type {type(value).__name__}; model files hold "
            f"None, booleans, numbers, strings, lists, tuples and numeric arrays only."
        )

    def _scalar(self, value, what):
        dtype = value.dtype
        if dtype.kind not in SCALAR_KINDS:
            raise TypeError(
                f"cannot save {what}: a numpy scalar of dtype {dtype}; model files hold "
                f"boolean, integer, floating-point and string scalars only."
            )
        if dtype.kind == "f" and dtype.itemsize > 8 and float(value) != value:
            raise TypeError(
                f"cannot save {what}: {value!r} has more precision than a float64 carries; "
                f"pass it as a float."
            )
        number = value.item()
        if dtype.kind == "f":
            number = _special(float(number))
        return {"scalar": number, "dtype": dtype.str}

    def _array(self, array, what):
        if array.dtype.kind == "O":
            if array.ndim != 1:
                raise TypeError(
                    f"cannot save {what}: an object array of {array.ndim} dimensions; model "
                    f"files hold numeric arrays, and 1-D arrays of strings or numbers."
                )
            return {"items": [self.encode(v, what) for v in array], "as": "object"}
        if array.dtype.kind not in ARRAY_KINDS or array.dtype.fields:
            raise TypeError(
                f"cannot save {what}: an array of dtype {array.dtype}; model files hold "
                f"booleans, integers, floats and strings only."
            )
        name = f"arrays/{len(self.arrays):04d}.npy"
        self.arrays[name] = array
        return {"array": name, "shape": list(array.shape), "dtype": array.dtype.str,
                "as": "ndarray"}


def is_reference(value):
    """Whether ``value`` (parsed JSON) has the form of a reference to an array member."""
    return isinstance(value, dict) and set(value) == REFERENCE_KEYS


def reference(value, where, what):
    """``(member, shape, dtype, as)`` of a reference, each checked for its form; else refuse."""
    if not is_reference(value):
        raise ModelFileError(f"{where}: {what} is not an array reference.")
    shape, dtype, member, kind = value["shape"], value["dtype"], value["array"], value["as"]
    if not (
        isinstance(shape, list) and len(shape) <= 8
        and all(type(n) is int and 0 <= n < 2**62 for n in shape)
    ):
        raise ModelFileError(f"{where}: {what} declares shape {str(shape)[:60]}.")
    dtype = parse_dtype(dtype, ARRAY_KINDS)
    if dtype is None:
        raise ModelFileError(
            f"{where}: {what} declares dtype {str(value['dtype'])[:20]!r}; model arrays are "
            f"booleans, integers or floats."
        )
    if not isinstance(member, str) or kind not in ("ndarray", "list", "tuple"):
        raise ModelFileError(f"{where}: {what} names no array member.")
    return member, tuple(shape), dtype, kind


def decode(value, where, what, read_array, depth=0):
    """The value an :meth:`Encoder.encode` result stands for.

    ``read_array(member, shape, dtype, what)`` reads a referenced array (after
    checking that its size is allowed where it occurs).
    """
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, dict):
        keys = set(value)
        if keys == {"float"} and value["float"] in SPECIAL_FLOATS:
            return SPECIAL_FLOATS[value["float"]]
        if keys == {"scalar", "dtype"}:
            return _decode_scalar(value, where, what)
        kind = value.get("as")
        if keys == {"items", "as"} and isinstance(value["items"], list) and depth < MAX_DEPTH:
            items = [decode(v, where, what, read_array, depth + 1) for v in value["items"]]
            if kind == "list":
                return items
            if kind == "tuple":
                return tuple(items)
            if kind == "object":
                array = np.empty(len(items), dtype=object)
                for k, item in enumerate(items):
                    array[k] = item
                return array
        if keys == {"strings", "as"} and _is_string_list(value["strings"]):  # format 1
            array = np.array(value["strings"], dtype=object)
            if kind == "ndarray":
                return array
            if kind in ("list", "tuple"):
                return list(value["strings"]) if kind == "list" else tuple(value["strings"])
        if is_reference(value):
            member, shape, dtype, kind = reference(value, where, what)
            array = read_array(member, shape, dtype, what)
            if kind == "ndarray":
                return array
            # Format 1 stored lists and tuples as arrays.
            return array.tolist() if kind == "list" else tuple(array.tolist())
    raise ModelFileError(
        f"{where}: {what} holds {str(value)[:80]!r}, which is no value a model file can hold; "
        f"the file is corrupted or was not written by sk_hamiltonian.save."
    )


def _decode_scalar(value, where, what):
    number, text = value["scalar"], value["dtype"]
    dtype = parse_dtype(text, SCALAR_KINDS)
    if dtype is None:
        raise ModelFileError(
            f"{where}: {what} declares a scalar of dtype {str(text)[:20]!r}; model files "
            f"hold boolean, integer, floating-point and string scalars."
        )
    expected = {"b": bool, "i": int, "u": int, "f": (int, float), "U": str}[dtype.kind]
    if isinstance(number, str) and dtype.kind == "f" and number in SPECIAL_FLOATS:
        number = SPECIAL_FLOATS[number]
    if not isinstance(number, expected) or (dtype.kind != "b" and isinstance(number, bool)):
        raise ModelFileError(
            f"{where}: {what} holds {str(number)[:40]!r} as a scalar of dtype {dtype}; the file "
            f"is corrupted."
        )
    if dtype.kind in "iu" and not np.iinfo(dtype).min <= number <= np.iinfo(dtype).max:
        raise ModelFileError(f"{where}: {what}: {number} does not fit into dtype {dtype}.")
    if dtype.kind == "U" and len(number) * 4 > dtype.itemsize:
        raise ModelFileError(f"{where}: {what}: {number[:40]!r} does not fit into dtype {dtype}.")
    with np.errstate(over="ignore"):
        scalar = dtype.type(number)
    if dtype.kind == "f" and math.isfinite(number) and not np.isfinite(scalar):
        raise ModelFileError(f"{where}: {what}: {number} does not fit into dtype {dtype}.")
    return scalar


def parse_dtype(text, kinds):
    """The numpy dtype ``text`` names if it is a plain one of ``kinds``, else None."""
    if not isinstance(text, str) or not DTYPE_TEXT.match(text):
        return None
    try:
        dtype = np.dtype(text)
    except TypeError:
        return None
    return dtype if dtype.kind in kinds else None


def _is_string_list(value):
    return isinstance(value, list) and all(isinstance(v, str) for v in value)
