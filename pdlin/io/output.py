"""Safe output files: checks before the work, atomic replacement after it.

Every pdlin writer builds its files in a private staging folder next to the
target (:func:`staging`) and moves them into place only when they are
complete, so a run that fails, is killed, fills the disk or hits the
file-size limit never leaves a truncated file, and the previous version of
the target stays as it was.  Outputs made of several files (a ``.pvd``
collection and its VTU pieces, an ``.xdmf`` file and its HDF5 data) give the
companion files a version tag, a hash of their data (``run.pvd.<tag>/``,
``run.xdmf.<tag>.h5``) and replace the main file last, by one rename: the
main file always refers to one complete set of companions; the old set is
removed after the switch.

:func:`check_output` and :func:`pdlin.plotting.check_figure` are what the ``pdlin`` command
runs before any work: the suffix, the optional library the format needs and a
writable folder.
"""

from __future__ import annotations

import errno
import logging
import os
import re
import secrets
import shutil
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .._lazy import moved_attribute
from ..errors import InputError, MissingDependencyError, WriteError

log = logging.getLogger(__name__)

__all__ = [
    "Stage",
    "staging",
    "data_tag",
    "write_error",
    "need_module",
    "check_output",
    "check_folder",
    "OPTIONAL_MODULES",
]

#: output suffix -> (module it needs, pdlin extra that installs it)
OPTIONAL_MODULES: dict[str, tuple[str, str]] = {
    ".xdmf": ("h5py", "io"),
    ".e": ("netCDF4", "exodus"),
    ".exo": ("netCDF4", "exodus"),
}

_TAG_LEN = 8  # hex digits of a companion's version tag


def need_module(module: str, extra: str, what: str) -> Any:
    """Import ``module`` or raise :class:`~pdlin.errors.MissingDependencyError`.

    Parameters
    ----------
    module : str
        Module to import (``'h5py'``, ``'netCDF4'``, ...).
    extra : str
        pdlin's optional extra that installs it, named in the message.
    what : str
        The feature that needs it, first words of the message.

    Returns
    -------
    module
        The imported module.

    Raises
    ------
    MissingDependencyError
        When the import fails (chained to the ImportError).

    Examples
    --------
    >>> need_module("numpy", "none", "arrays").__name__
    'numpy'
    >>> need_module("no_such_module_pdlin", "io", ".xdmf output")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.MissingDependencyError: .xdmf output needs no_such_module_pdlin: pip install ...
    """
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingDependencyError(
            f"{what} needs {module}: pip install 'pdlin[{extra}]'"
        ) from exc


def write_error(target: str | Path, exc: OSError) -> WriteError:
    """Build a :class:`~pdlin.errors.WriteError` naming ``target`` and the reason of ``exc``.

    Parameters
    ----------
    target : str or Path
        The file the caller was writing.
    exc : OSError
        The failure; a :class:`~pdlin.errors.WriteError` is returned unchanged.

    Returns
    -------
    WriteError
        ``cannot write '<target>': <reason>``, the reason naming a full disk or the
        file-size limit where the errno (or numpy's short-write message) shows it.
    """
    if isinstance(exc, WriteError):
        return exc
    reason = exc.strerror or str(exc) or type(exc).__name__
    if exc.errno == errno.EFBIG:
        reason += " (the file-size limit, ulimit -f, was reached)"
    elif exc.errno is None and re.search(r"requested and \d+ written", reason):
        # numpy's tofile on a short write: the OS error itself is not reported
        reason += " (a short write: the disk is full or the file-size limit was reached)"
    where = f" ({exc.filename})" if exc.filename and Path(str(exc.filename)).name else ""
    if where and Path(str(exc.filename)) == Path(target):
        where = ""
    return WriteError(f"cannot write {str(target)!r}: {reason}{where}")


def check_folder(path: str | Path, what: str = "output") -> Path:
    """Check that ``path`` can be created as a file in a writable folder.

    Its folder, or the nearest existing ancestor (the writers create the rest), must be
    a writable folder, and ``path`` itself must not be a folder.

    Parameters
    ----------
    path : str or Path
        The file to be written.
    what : str
        How the messages name the path.

    Returns
    -------
    Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    InputError
        ``path`` is a folder, or an ancestor is a file.
    WriteError
        The folder is not writable.
    """
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{what} {str(p)!r} is a folder; expected a file path")
    anc = p.absolute().parent
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        raise InputError(f"{what} {str(p)!r}: {str(anc)!r} is a file, not a folder")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise WriteError(f"cannot write {str(p)!r}: folder {str(anc)!r} is not writable")
    return p


def check_output(path: str | Path, suffixes: Iterable[str], what: str = "output path") -> Path:
    """Check an output path before the work: suffix, optional library, writable folder.

    Parameters
    ----------
    path : str or Path
        The file to be written.
    suffixes : iterable of str
        Allowed suffixes (lower case, with the dot).
    what : str
        How the messages name the path (``"-o/--output"``, ``"output.path"``, ...).

    Returns
    -------
    Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    InputError
        Wrong suffix, or the path is a folder.
    MissingDependencyError
        The format needs a library that is not installed (``.xdmf``: h5py,
        ``.e``/``.exo``: netCDF4).
    WriteError
        The folder is not writable.

    Examples
    --------
    >>> import tempfile, os
    >>> d = tempfile.mkdtemp()
    >>> check_output(os.path.join(d, "new", "r.npz"), (".npz", ".vtu")).name
    'r.npz'
    >>> check_output(os.path.join(d, "r.txt"), (".npz", ".vtu"))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.InputError: output path must end with one of ('.npz', '.vtu'), got '.../r.txt'
    """
    p = Path(path)
    allowed = tuple(suffixes)
    suffix = p.suffix.lower()
    if suffix not in allowed:
        raise InputError(f"{what} must end with one of {allowed}, got {str(p)!r}")
    if suffix in OPTIONAL_MODULES:
        module, extra = OPTIONAL_MODULES[suffix]
        need_module(module, extra, f"{suffix} output ({str(p)!r})")
    return check_folder(p, what)


@dataclass(frozen=True)
class Stage:
    """Where a writer puts its files: ``dir`` (private), named for ``target``.

    The main file goes to ``dir / target.name``; companions (data the main
    file refers to) are named :meth:`companion` so a new set never overwrites
    the set the old main file refers to.
    """

    dir: Path
    target: Path
    tag: str

    @property
    def main(self) -> Path:
        """Where the writer puts the main file."""
        return self.dir / self.target.name

    def companion(self, ext: str = "") -> str:
        """Return the versioned name of a companion file or folder.

        Parameters
        ----------
        ext : str
            Suffix appended after the tag (e.g. ``'.h5'``; empty for a folder).

        Returns
        -------
        str
            ``<target name>.<tag><ext>`` (a name, not a path).
        """
        return f"{self.target.name}.{self.tag}{ext}"


def _companion_re(target: Path) -> re.Pattern[str]:
    return re.compile(rf"^{re.escape(target.name)}\.[0-9a-f]{{{_TAG_LEN}}}(\.h5)?$")


def _legacy_companions(target: Path) -> list[Path]:
    """List the unversioned companions the current ``target`` refers to.

    These are the files of older pdlin versions: ``<stem>_0001.vtu`` ... of a ``.pvd``,
    ``<stem>.h5`` of an ``.xdmf``.
    """
    if not target.is_file():
        return []
    suffix = target.suffix.lower()
    try:
        if suffix == ".pvd":
            piece = re.compile(rf"^{re.escape(target.stem)}_\d{{4,}}\.vtu$")
            names = [str(e.get("file", "")) for e in ET.parse(target).getroot().iter("DataSet")]
            return [target.parent / n for n in names if piece.match(n)]
        if suffix == ".xdmf":
            h5 = f"{target.stem}.h5"
            if f">{h5}:" in target.read_text(errors="replace"):
                return [target.parent / h5]
    except (OSError, ET.ParseError):
        pass
    return []


def _listed(target: Path, companion: Path) -> bool:
    """Whether the current ``target`` refers to ``companion`` (kept on a failed write)."""
    try:
        return target.is_file() and companion.name in target.read_text(errors="replace")
    except OSError:
        return True


def _remove(p: Path) -> None:
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    else:
        p.unlink(missing_ok=True)


def data_tag(*parts: Any) -> str:
    """Hash the data written into a version tag, so one result gets one companion name.

    Parameters
    ----------
    *parts : object
        Arrays, numbers, strings, and mappings / sequences of them (keys, lengths,
        dtypes and shapes are hashed too).

    Returns
    -------
    str
        8 hex digits (BLAKE2b).

    Examples
    --------
    >>> import numpy as np
    >>> a = data_tag({"u": np.ones(3)}, [1.0, 2.0])
    >>> len(a), a == data_tag({"u": np.ones(3)}, [1.0, 2.0]), a == data_tag({"u": np.zeros(3)})
    (8, True, False)
    """
    import hashlib

    import numpy as np

    h = hashlib.blake2b(digest_size=_TAG_LEN // 2)

    def feed(x: Any) -> None:
        if isinstance(x, Mapping):
            for k, v in x.items():
                feed(str(k))
                feed(v)
        elif isinstance(x, list | tuple):
            h.update(b"[%d" % len(x))
            for v in x:
                feed(v)
        elif isinstance(x, str):
            h.update(b"s" + x.encode() + b"\0")
        else:
            a = np.ascontiguousarray(x)
            h.update(f"a{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes())

    for part in parts:
        feed(part)
    return h.hexdigest()


@contextmanager
def staging(target: str | Path, tag: str | None = None) -> Iterator[Stage]:
    """Stage files in a private folder next to ``target``; they replace theirs on success.

    Companions are moved first, the main file (``target.name``) last; then the
    companions of earlier versions are removed.  ``tag`` names the companions
    (:func:`data_tag` of the data: the same result gets the same names, a
    companion already there with that name holds the same data and is kept);
    default a random one.  Any ``OSError`` (full disk,
    file-size limit, permissions) becomes a :class:`~pdlin.errors.WriteError`
    naming ``target``; the staging folder is removed and ``target`` is left as
    it was.

    Parameters
    ----------
    target : str or Path
        The main file to (re)write.
    tag : str, optional
        Version tag of the companions (default: random).

    Yields
    ------
    Stage
        The staging folder and the names to write into it.

    Raises
    ------
    WriteError
        When writing or moving a file fails.

    Examples
    --------
    >>> import tempfile, os
    >>> d = tempfile.mkdtemp()
    >>> with staging(os.path.join(d, "a.txt")) as st:
    ...     _ = st.main.write_text("hello")
    >>> os.listdir(d)
    ['a.txt']
    """
    t = Path(target)
    try:
        t.parent.mkdir(parents=True, exist_ok=True)
        # staging folders of this target left by a killed writer (a finished or failed
        # write removes its own): clear them, they never hold a complete result
        for stale in t.parent.glob(f".{t.name}.*.partial"):
            shutil.rmtree(stale, ignore_errors=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{t.name}.", suffix=".partial", dir=t.parent))
    except OSError as exc:
        raise write_error(t, exc) from exc
    stage = Stage(tmp, t, tag if tag is not None else secrets.token_hex(_TAG_LEN // 2))
    moved: list[Path] = []
    try:
        yield stage
        legacy = _legacy_companions(t)
        # companions first, the file that refers to them (or the only file) last
        for f in sorted(tmp.iterdir(), key=lambda f: f.name == t.name):
            dest = t.parent / f.name
            if f.is_dir() and dest.is_dir() and f.name != t.name:
                # a companion folder of the same data tag: the same data, complete
                # (companions are moved in only when complete); keep it
                moved.append(dest)
                continue
            os.replace(f, dest)
            moved.append(dest)
    except OSError as exc:
        for m in moved:
            if m != t and not _listed(t, m):
                _remove(m)
        raise write_error(t, exc) from exc
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    # the new version is in place: remove the companions of earlier ones
    # (and of writers killed between moving their companions and their main file)
    pattern = _companion_re(t)
    old = [f for f in t.parent.iterdir() if pattern.match(f.name) and f not in moved]
    for f in old + legacy:
        _remove(f)


def __getattr__(name: str) -> Any:  # check_figure moved to pdlin.plotting (deprecated here)
    return moved_attribute(__name__, {"check_figure": "pdlin.plotting"}, name)
