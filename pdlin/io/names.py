"""File names of pdlin's point fields: ParaView- and Peridigm-friendly, and back.

pdlin's Python API keys its fields in snake case (``result.fields()``:
``displacement``, ``reaction``, ...).  The ParaView formats (VTU, PVD, XDMF,
Exodus II) store them under the names Peridigm writes where Peridigm has the
quantity (``Displacement``, ``Volume``, ``Number_Of_Neighbors``,
``Deformation_Gradient``, ``Cauchy_Stress``, ``Damage``, ``Block_Id``) and
capitalized names otherwise (``Reaction_Force``, ``Strain``).  NPZ files keep
the API keys (they are read from Python).  :func:`api_name` maps a file name
(new or the lowercase names of pdlin files written before) back to the API key.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "FILE_NAMES",
    "TENSOR_FIELDS",
    "VECTOR_FIELDS",
    "file_name",
    "api_name",
    "to_file_value",
    "from_file_value",
]

#: API key -> name in ParaView / Exodus files
FILE_NAMES: dict[str, str] = {
    "displacement": "Displacement",
    "reaction": "Reaction_Force",
    "volume": "Volume",
    "family_size": "Number_Of_Neighbors",
    "material": "Block_Id",
    "deformation_gradient": "Deformation_Gradient",
    "strain": "Strain",
    "stress": "Cauchy_Stress",
    "damage": "Damage",
}
#: fields with one component per coordinate direction (written as 3-vectors)
VECTOR_FIELDS = frozenset({"displacement", "reaction"})
#: fields holding a dim x dim tensor per point (written as 3 x 3 tensors)
TENSOR_FIELDS = frozenset({"deformation_gradient", "strain", "stress"})

_BACK = {v: k for k, v in FILE_NAMES.items()}


def file_name(key: str) -> str:
    """Name the API field ``key`` as it is written to ParaView formats.

    ``state_<name>`` (state variables of nonlinear runs) becomes
    ``State_<name>``; other unknown keys are written unchanged.

    Parameters
    ----------
    key : str
        Field key of the API (``'displacement'``, ``'stress'``, ...).

    Returns
    -------
    str
        The file's field name (Peridigm's spelling where one exists).

    Examples
    --------
    >>> file_name("displacement"), file_name("stress"), file_name("state_gamma"), file_name("u")
    ('Displacement', 'Cauchy_Stress', 'State_gamma', 'u')
    """
    if key in FILE_NAMES:
        return FILE_NAMES[key]
    if key.startswith("state_"):
        return "State_" + key[6:]
    return key


def api_name(name: str) -> str:
    """Return the API key of a field read from a file (inverse of :func:`file_name`).

    Lowercase names of files written by earlier pdlin versions map to
    themselves, so both spellings read back to the same key.

    Parameters
    ----------
    name : str
        Field name in the file.

    Returns
    -------
    str
        The API key.

    Examples
    --------
    >>> api_name("Displacement"), api_name("displacement"), api_name("State_gamma")
    ('displacement', 'displacement', 'state_gamma')
    """
    if name in _BACK:
        return _BACK[name]
    if name.startswith("State_"):
        return "state_" + name[6:]
    return name


def to_file_value(key: str, arr: np.ndarray, dim: int) -> np.ndarray:
    """Pad a field for a 3D viewer: vectors to (n, 3), dim x dim tensors to (n, 9).

    ``material`` (0-based phase ids) is written as Peridigm's 1-based ``Block_Id``.

    Parameters
    ----------
    key : str
        API key of the field.
    arr : (n,) or (n, k) array_like
        The field's values.
    dim : {1, 2, 3}
        Dimension of the result.

    Returns
    -------
    ndarray
        float64: ``(n, 3)`` for a ``dim``-vector, ``(n, 9)`` for a tensor (zero-padded,
        row-major), ``material + 1`` for ``material``, else ``arr`` unchanged.
    """
    arr = np.asarray(arr, dtype=float)
    n = arr.shape[0]
    if key == "material":
        return arr + 1.0
    if key in TENSOR_FIELDS and arr.ndim == 2 and arr.shape[1] == dim * dim and dim < 3:
        t = np.zeros((n, 3, 3))
        t[:, :dim, :dim] = arr.reshape(n, dim, dim)
        return t.reshape(n, 9)
    if arr.ndim == 2 and arr.shape[1] == dim and dim < 3 and key not in TENSOR_FIELDS:
        out = np.zeros((n, 3))
        out[:, :dim] = arr
        return out
    return arr


def from_file_value(name: str, arr: np.ndarray, dim: int) -> tuple[str, np.ndarray]:
    """Undo :func:`to_file_value` for a field named ``name`` in a file of a ``dim``-D result.

    Parameters
    ----------
    name : str
        Field name in the file.
    arr : (n,) or (n, k) array_like
        The values read.
    dim : {1, 2, 3}
        Dimension of the result.

    Returns
    -------
    key : str
        The API key.
    value : ndarray
        The array without its padding (``Block_Id`` back to 0-based ``material``; the
        lowercase ``material`` of older files is 0-based already).
    """
    key = api_name(name)
    arr = np.asarray(arr, dtype=float)
    n = arr.shape[0]
    if name == "Block_Id":
        return key, arr - 1.0
    if key in TENSOR_FIELDS and arr.ndim == 2 and arr.shape[1] == 9 and dim < 3:
        return key, arr.reshape(n, 3, 3)[:, :dim, :dim].reshape(n, dim * dim)
    if key in VECTOR_FIELDS and arr.ndim == 2 and arr.shape[1] == 3 and dim < 3:
        return key, arr[:, :dim]
    return key, arr
