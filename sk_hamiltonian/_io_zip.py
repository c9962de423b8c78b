"""The container of a model file: a zip of one JSON manifest and ``.npy`` arrays.

Reading never trusts the file: member names are checked against a fixed
pattern before anything is read, every size is checked before the bytes are
read (and reading stops at the declared size, whatever the compressed stream
says), and arrays are parsed with ``allow_pickle=False`` after their header
has been checked against the manifest.
"""

import io
import json
import re
import zipfile
import zlib

import numpy as np

#: The manifest's member name.
MANIFEST = "manifest.json"
#: Members allowed in a file: the manifest and numbered arrays, nothing else
#: (no directories, no absolute paths, no ``..``, no backslashes).
MEMBER_NAME = re.compile(r"\A(?:manifest\.json|arrays/[0-9]{1,6}\.npy)\Z")

# Limits (bytes, counts). Models of this package are small: 10 000 unknowns
# of 20 state variables take under 2 MB. The limits only stop a file from
# claiming more memory than a model can use.
MAX_MANIFEST_BYTES = 4 * 2**20
MAX_ARRAY_BYTES = 256 * 2**20
MAX_TOTAL_BYTES = 1024 * 2**20
MAX_MEMBERS = 10_000
MAX_JSON_DEPTH = 32
# Array element types a model holds: booleans, integers, floats.
ARRAY_KINDS = "biuf"


class ModelFileError(ValueError):
    """A model file is malformed, unsafe, or from an incompatible version.

    Raised by :func:`sk_hamiltonian.load` (and
    :func:`sk_hamiltonian.io.read_manifest`) with a message naming the file,
    the problem and what to do; nothing in the file is executed. A
    subclass of :class:`ValueError`.
    """


def write_container(path, manifest, arrays):
    """Write ``manifest`` (a JSON-able dict) and ``arrays`` (name -> ndarray) to ``path``."""
    text = json.dumps(manifest, indent=1, sort_keys=True, allow_nan=False)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(MANIFEST, text)
        for name, array in arrays.items():
            buffer = io.BytesIO()
            np.lib.format.write_array(buffer, np.ascontiguousarray(array), allow_pickle=False)
            archive.writestr(name, buffer.getvalue())


class Container:
    """An open model file whose member list has been checked.

    Parameters
    ----------
    path : str or path-like or file object
        The file.
    where : str
        How to name the file in messages.
    """

    def __init__(self, path, where):
        self.where = where
        try:
            self.archive = zipfile.ZipFile(path, "r")
        except FileNotFoundError:
            raise ModelFileError(f"{where}: file not found.") from None
        except IsADirectoryError:
            raise ModelFileError(f"{where} is a directory, not a model file.") from None
        except (zipfile.BadZipFile, OSError, EOFError, ValueError, NotImplementedError,
                UnicodeDecodeError) as error:
            raise ModelFileError(
                f"{where} is not a model file of sk_hamiltonian (not a readable zip archive: "
                f"{error}). Model files are written by sk_hamiltonian.save; a truncated or "
                f"corrupted download also gives this error: fetch the file again."
            ) from None
        try:
            self.members = self._check_members()
        except BaseException:
            self.archive.close()
            raise

    def close(self):
        self.archive.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def fail(self, problem):
        raise ModelFileError(f"{self.where}: {problem}")

    def _check_members(self):
        infos = self.archive.infolist()
        if len(infos) > MAX_MEMBERS:
            self.fail(f"{len(infos)} members, more than a model file holds ({MAX_MEMBERS}).")
        members, total = {}, 0
        for info in infos:
            name = info.filename
            if not MEMBER_NAME.match(name):
                self.fail(
                    f"unexpected member {name!r}: a model file holds only 'manifest.json' and "
                    f"'arrays/<number>.npy'; this file was not written by sk_hamiltonian.save "
                    f"and is refused."
                )
            if name in members:
                self.fail(f"member {name!r} appears twice; the file is refused.")
            if info.flag_bits & 0x1:
                self.fail(f"member {name!r} is encrypted; model files never are.")
            if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
                self.fail(
                    f"member {name!r} uses compression method {info.compress_type}; model "
                    f"files use only 'stored' or 'deflated'."
                )
            limit = MAX_MANIFEST_BYTES if name == MANIFEST else MAX_ARRAY_BYTES
            if info.file_size > limit:
                self.fail(
                    f"member {name!r} declares {info.file_size} bytes, more than the limit of "
                    f"{limit} bytes for a model file; the file is refused before reading it. "
                    f"If you trust it and it really is this large, raise "
                    f"sk_hamiltonian._io_zip.MAX_ARRAY_BYTES."
                )
            total += info.file_size
            members[name] = info
        if total > MAX_TOTAL_BYTES:
            self.fail(
                f"members declare {total} bytes in all, more than the limit of "
                f"{MAX_TOTAL_BYTES}; the file is refused before reading it."
            )
        if MANIFEST not in members:
            self.fail(
                "no 'manifest.json': not a model file of sk_hamiltonian (write one with "
                "sk_hamiltonian.save)."
            )
        return members

    def read_bytes(self, name):
        """The bytes of member ``name``, never more than it declares."""
        info = self.members.get(name)
        if info is None:
            self.fail(f"the manifest refers to {name!r}, which the file does not hold.")
        try:
            with self.archive.open(info) as stream:
                data = stream.read(info.file_size + 1)
        except (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError,
                NotImplementedError) as error:
            self.fail(
                f"member {name!r} cannot be read ({error}): the file is corrupted or "
                f"truncated; fetch it again."
            )
        if len(data) != info.file_size:
            self.fail(
                f"member {name!r} holds {len(data)} bytes where it declares {info.file_size}; "
                f"the file is corrupted."
            )
        return data

    def read_manifest(self):
        """The manifest, parsed as JSON into plain dicts, lists and scalars."""
        text = self.read_bytes(MANIFEST)
        try:
            manifest = json.loads(text.decode("utf-8"), parse_constant=self._no_constant)
        except (UnicodeDecodeError, ValueError, RecursionError) as error:
            self.fail(f"'manifest.json' is not valid JSON ({error}); the file is corrupted.")
        if json_depth(manifest) > MAX_JSON_DEPTH:
            self.fail("'manifest.json' is nested deeper than any model manifest.")
        if not isinstance(manifest, dict):
            self.fail("'manifest.json' does not hold a JSON object.")
        return manifest

    def _no_constant(self, name):
        self.fail(f"'manifest.json' holds {name}, which is not JSON; the file is corrupted.")

    def read_array(self, name, shape, dtype):
        """The array of member ``name``, checked to have ``shape`` and ``dtype``."""
        data = self.read_bytes(name)
        stream = io.BytesIO(data)
        try:
            version = np.lib.format.read_magic(stream)
            if version == (1, 0):
                header = np.lib.format.read_array_header_1_0(stream, max_header_size=10_000)
            elif version == (2, 0):
                header = np.lib.format.read_array_header_2_0(stream, max_header_size=10_000)
            else:
                raise ValueError(f"unsupported .npy version {version}")
        except Exception as error:  # numpy parses the header as a Python literal
            self.fail(f"array {name!r} has no valid .npy header ({error}); the file is corrupted.")
        found_shape, fortran, found_dtype = header
        if found_dtype.hasobject or found_dtype.kind not in ARRAY_KINDS or found_dtype.fields:
            self.fail(
                f"array {name!r} has dtype {found_dtype}; model arrays are booleans, integers "
                f"or floats only (object arrays could carry a pickle, and are refused)."
            )
        if tuple(found_shape) != tuple(shape) or found_dtype != np.dtype(dtype):
            self.fail(
                f"array {name!r} has shape {tuple(found_shape)} and dtype {found_dtype}, but the "
                f"manifest declares {tuple(shape)} and {dtype}; the file is corrupted."
            )
        expected = stream.tell() + _n_elements(shape) * found_dtype.itemsize
        if expected != len(data):
            self.fail(
                f"array {name!r} holds {len(data)} bytes; its header declares {expected}. The "
                f"file is corrupted or truncated."
            )
        try:
            array = np.lib.format.read_array(io.BytesIO(data), allow_pickle=False)
        except (ValueError, OSError, EOFError) as error:  # pragma: no cover - checked above
            self.fail(f"array {name!r} cannot be read ({error}).")
        return array


def _n_elements(shape):
    count = 1
    for n in shape:
        count *= int(n)
    return count


def json_depth(value, depth=0):
    """Nesting depth of a parsed JSON value (iterative, so no recursion limit)."""
    deepest, stack = depth, [(value, depth)]
    while stack:
        item, level = stack.pop()
        deepest = max(deepest, level)
        if isinstance(item, dict):
            stack.extend((v, level + 1) for v in item.values())
        elif isinstance(item, list):
            stack.extend((v, level + 1) for v in item)
    return deepest
