"""The container of a model file: a zip of one JSON manifest and ``.npy`` arrays.

Reading never trusts the file: member names are checked against a fixed
pattern before anything is read, every member must be referred to exactly
once by the manifest, a member's size must fit the shape and dtype its
reference declares before its bytes are read (and reading stops at the
declared size, whatever the compressed stream says), and arrays are parsed
with ``allow_pickle=False`` after their header has been checked against the
manifest. Writing to a path is atomic (:func:`write_container`).
"""

import contextlib
import io
import json
import os
import re
import secrets
import stat
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
# Longest .npy header read: numpy writes about 128 bytes for a model's arrays.
MAX_HEADER_BYTES = 4096
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
    """Write ``manifest`` (a JSON-able dict) and ``arrays`` (name -> ndarray) to ``path``.

    A path is written atomically: into a new file beside it, flushed and
    synced to disk, then renamed over it (``os.replace``). An error, an
    interrupt or a full disk while writing removes that file and leaves an
    existing ``path`` as it was; a killed process can leave only the hidden
    ``.<name>.<random>.tmp`` beside it, never a partial ``path``. A file object
    is written in place.
    """
    text = json.dumps(manifest, indent=1, sort_keys=True, allow_nan=False)
    if not (isinstance(path, (str, bytes)) or hasattr(path, "__fspath__")):
        _write_zip(path, text, arrays)
        return
    target = os.path.realpath(os.fsdecode(os.fspath(path)))
    stream, temporary = _create_beside(target)
    try:
        with stream:
            _write_zip(stream, text, arrays)
            stream.flush()
            os.fsync(stream.fileno())
        _copy_mode(target, temporary)
        os.replace(temporary, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise
    _sync_folder(os.path.dirname(target))


def _write_zip(stream, text, arrays):
    with zipfile.ZipFile(stream, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(MANIFEST, text)
        for name, array in arrays.items():
            _write_member(archive, name, array)


def _write_member(archive, name, array):
    with archive.open(name, "w", force_zip64=array.nbytes > 2**30) as member:
        np.lib.format.write_array(member, np.ascontiguousarray(array), allow_pickle=False)


def _create_beside(target):
    """A new file, open for writing, in the folder of ``target``: ``(stream, its path)``."""
    folder, base = os.path.split(target)
    for _ in range(100):
        temporary = os.path.join(folder, f".{base}.{secrets.token_hex(4)}.tmp")
        try:
            # 0o666 as open() would use, so that the umask applies as for any new file.
            fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL
                         | getattr(os, "O_BINARY", 0), 0o666)
        except FileExistsError:
            continue
        except OSError as error:
            # Name the file the caller asked for, not the temporary one.
            raise type(error)(error.errno, error.strerror, target) from None
        return os.fdopen(fd, "wb"), temporary
    raise FileExistsError(f"cannot create a temporary file beside {target}")


def _copy_mode(target, temporary):
    """Give the new file the permissions of the one it replaces (as overwriting kept them)."""
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except OSError:
        return
    with contextlib.suppress(OSError):
        os.chmod(temporary, mode)


def _sync_folder(folder):
    """Make the rename durable (POSIX); where folders cannot be opened, nothing to do."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


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
        self.referenced = set()

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

    def check_references(self, value):
        """Each array member referenced exactly once in ``value`` (parsed JSON), nothing else held.

        Runs before any array is read, so that no member can be read twice
        (one large array standing for many attributes) and no member lies in
        the file unaccounted for.
        """
        names, stack = [], [value]
        while stack:
            item = stack.pop()
            if isinstance(item, dict):
                if isinstance(item.get("array"), str):
                    names.append(item["array"])
                stack.extend(item.values())
            elif isinstance(item, list):
                stack.extend(item)
        seen = set()
        for name in names:
            if name in seen:
                self.fail(
                    f"the manifest refers to member {name[:40]!r} more than once; each array "
                    f"of a model file stands for one value. The file is refused."
                )
            if name not in self.members:
                self.fail(f"the manifest refers to {name[:40]!r}, which the file does not hold.")
            seen.add(name)
        unreferenced = sorted(set(self.members) - seen - {MANIFEST})
        if unreferenced:
            self.fail(
                f"the file holds {len(unreferenced)} member(s) the manifest does not refer to "
                f"({', '.join(unreferenced[:3])}); the file is refused."
            )

    def expect(self, name, shape, dtype, what):
        """Refuse, before reading it, a member larger than an array of ``shape`` and ``dtype``."""
        info = self.members.get(name)
        if info is None:
            self.fail(f"the manifest refers to {name!r}, which the file does not hold.")
        needed = _n_elements(shape) * np.dtype(dtype).itemsize
        if not needed < info.file_size <= needed + MAX_HEADER_BYTES:
            self.fail(
                f"member {name!r} ({what}) holds {info.file_size} bytes, but an array of shape "
                f"{tuple(shape)} and dtype {np.dtype(dtype)} takes {needed} (and a header); "
                f"the file is refused before reading it."
            )

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

    def read_array(self, name, shape, dtype, what="an array"):
        """The array of member ``name``, checked to have ``shape`` and ``dtype``.

        Each member is read at most once, and only if its size fits ``shape``
        and ``dtype``.
        """
        if name in self.referenced:
            self.fail(f"member {name!r} is referred to more than once; the file is refused.")
        self.expect(name, shape, dtype, what)
        self.referenced.add(name)
        data = self.read_bytes(name)
        stream = io.BytesIO(data)
        try:
            version = np.lib.format.read_magic(stream)
            read_header = {(1, 0): np.lib.format.read_array_header_1_0,
                           (2, 0): np.lib.format.read_array_header_2_0}.get(version)
            if read_header is not None:
                header = read_header(stream, max_header_size=MAX_HEADER_BYTES)
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
