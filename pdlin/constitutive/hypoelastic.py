"""Peridigm's hypoelastic stress update of its ``Elastic Correspondence`` material.

Peridigm's correspondence materials (``Peridigm_CorrespondenceMaterial.cpp``,
``correspondence.cxx``, ``elastic_correspondence.cxx``) integrate an isotropic
hypoelastic law in the unrotated frame of Flanagan & Taylor (1987), "An accurate
numerical algorithm for stress integration with finite rotations", Comput. Methods
Appl. Mech. Engrg. 62, 305-320 (their Eqs. 10-13, 36 and 44).  Over one load step
from the committed ``F_n`` (with the left stretch ``V_n``, the rotation ``R_n`` and the
unrotated Cauchy stress ``S_n``) to the trial ``F``, with Peridigm's quasi-static
velocity ``v = Δu / Δt`` (``Peridigm.cpp``, ``executeQuasiStatic``) and hence
``Ḟ Δt = F - F_n``:

    L Δt = (F - F_n) F⁻¹,  D = sym L,  W = skew L
    z_i = ε_ikj (D V_n)_jk,  w_i = -½ ε_ijk W_jk,  ω = w + (tr V_n I - V_n)⁻¹ z
    Ω_ij = ε_ikj ω_k,  Q = I + sin(Δt|ω|)/|ω| Ω - (1 - cos(Δt|ω|))/|ω|² Ω²
    R = Q R_n,  V = V_n + Δt (L V_n - V_n Ω),  d = Rᵀ D R
    S = S_n + 2 G dev(d Δt) + K tr(d Δt) I,  σ = R S Rᵀ,  P = J σ F⁻ᵀ

Every product is Peridigm's; ``Δt`` cancels.  The tangent ``∂P/∂F`` is the complex-step
derivative of this same function (Squire & Trapp 1998, "Using complex variables to
estimate derivatives of real functions", SIAM Review 40, 110-112): exact to round-off,
no difference step to choose.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError, ShapeError

__all__ = ["Hypoelastic"]

#: Levi-Civita symbol ε_ijk
_EPS = np.zeros((3, 3, 3))
for _a, _b, _c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _EPS[_a, _b, _c], _EPS[_a, _c, _b] = 1.0, -1.0
_EYE = np.eye(3)
#: complex step (Squire & Trapp 1998): any tiny h gives the derivative to round-off
_H = 1e-30


def _inv3(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse and determinant of ``(..., 3, 3)`` matrices by cofactors (real or complex).

    The cofactor formula of Peridigm's ``Invert3by3Matrix``; analytic, so the complex
    step passes through it.
    """
    c = np.empty_like(a)
    c[..., 0, 0] = a[..., 1, 1] * a[..., 2, 2] - a[..., 1, 2] * a[..., 2, 1]
    c[..., 0, 1] = a[..., 0, 2] * a[..., 2, 1] - a[..., 0, 1] * a[..., 2, 2]
    c[..., 0, 2] = a[..., 0, 1] * a[..., 1, 2] - a[..., 0, 2] * a[..., 1, 1]
    c[..., 1, 0] = a[..., 1, 2] * a[..., 2, 0] - a[..., 1, 0] * a[..., 2, 2]
    c[..., 1, 1] = a[..., 0, 0] * a[..., 2, 2] - a[..., 0, 2] * a[..., 2, 0]
    c[..., 1, 2] = a[..., 0, 2] * a[..., 1, 0] - a[..., 0, 0] * a[..., 1, 2]
    c[..., 2, 0] = a[..., 1, 0] * a[..., 2, 1] - a[..., 1, 1] * a[..., 2, 0]
    c[..., 2, 1] = a[..., 0, 1] * a[..., 2, 0] - a[..., 0, 0] * a[..., 2, 1]
    c[..., 2, 2] = a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]
    det = a[..., 0, 0] * c[..., 0, 0] + a[..., 0, 1] * c[..., 1, 0] + a[..., 0, 2] * c[..., 2, 0]
    return c / det[..., None, None], det


def _rotation_factors(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``sin(x)/x`` and ``(1 - cos x)/x²`` as functions of ``s = x²`` (analytic, complex too).

    ``(1 - cos x) = 2 sin²(x/2)`` avoids the cancellation; below ``|s| = 1e-6`` the
    series (truncation below 1e-21).  Peridigm takes ``Q = I`` for ``|ω|² <= 1e-30``,
    a difference of order ``|ω| Δt <= 1e-15``.
    """
    small = np.abs(s) < 1e-6
    safe = np.where(small, 1.0, s)
    x = np.sqrt(safe)
    f1 = np.where(small, 1.0 - s / 6.0 + s * s / 120.0, np.sin(x) / x)
    f2 = np.where(small, 0.5 - s / 24.0 + s * s / 720.0, 2.0 * np.sin(0.5 * x) ** 2 / safe)
    return f1, f2


class Hypoelastic:
    """Isotropic hypoelastic material: Peridigm's ``Elastic Correspondence`` stress update.

    The unrotated-frame update of Flanagan & Taylor (1987) as Peridigm implements it
    (module docstring): from the committed ``F_n``, left stretch ``V_n``, rotation
    ``R_n`` and unrotated Cauchy stress ``S_n`` to the trial ``F``, one quasi-static
    load step with the velocity ``(u - u_n) / Δt``.  3D only (Peridigm's decks are 3D).
    Use it as ``pdlin.Correspondence(material=Hypoelastic(K=..., G=...))`` or through
    :class:`pdlin.models.PeridigmCorrespondence`, which adds Peridigm's hourglass force.

    Parameters
    ----------
    K, G : float
        Bulk and shear modulus (``> 0``).

    Examples
    --------
    A uniaxial stretch from the undeformed state in one step: the unrotated update is
    ``S = K tr(d) I + 2 G dev(d)`` with ``d = (F - I) F⁻¹`` (no rotation):

    >>> import numpy as np
    >>> from pdlin.constitutive.hypoelastic import Hypoelastic
    >>> mat = Hypoelastic(K=5.0, G=3.0)
    >>> F = np.diag([1.01, 1.0, 1.0])[None]
    >>> P, state, A = mat.update(F, mat.initial_state(1), tangent=True)
    >>> d = 0.01 / 1.01
    >>> bool(np.isclose(P[0, 0, 0], (5.0 * d + 4.0 * d) * 1.01 / 1.01))
    True
    >>> A.shape
    (1, 3, 3, 3, 3)
    """

    dim = 3

    def __init__(self, K: float, G: float) -> None:
        for name, v in (("K", K), ("G", G)):
            if isinstance(v, bool) or not isinstance(v, int | float | np.number):
                raise InputError(f"{name} must be a positive number, got {v!r}")
            if not np.isfinite(v) or v <= 0:
                raise InputError(f"{name} must be a positive finite number, got {v}")
        self.K = float(K)
        self.G = float(G)

    def __repr__(self) -> str:
        """Short form with the moduli."""
        return f"Hypoelastic(K={self.K:g}, G={self.G:g})"

    def initial_state(self, n: int) -> dict[str, np.ndarray]:
        """Return the undeformed state of ``n`` points.

        Parameters
        ----------
        n : int
            Number of points (gradient points of a correspondence model).

        Returns
        -------
        dict of str -> ndarray
            ``F``, ``V``, ``R`` (identities) and ``S`` (zero unrotated Cauchy stress),
            each ``(n, 3, 3)``.
        """
        eye = np.broadcast_to(_EYE, (n, 3, 3)).copy()
        return {"F": eye, "V": eye.copy(), "R": eye.copy(), "S": np.zeros((n, 3, 3))}

    def _step(
        self, F: np.ndarray, F0: np.ndarray, V0: np.ndarray, R0: np.ndarray, S0: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """One load step (arrays broadcast; real or complex ``F``) -> P, V, R, S."""
        Finv, J = _inv3(F)
        L = (F - F0) @ Finv  # L Δt
        Lt = np.swapaxes(L, -1, -2)
        D = 0.5 * (L + Lt)
        W = 0.5 * (L - Lt)
        z = np.einsum("ikj,...jk->...i", _EPS, D @ V0)
        w = -0.5 * np.einsum("ijk,...jk->...i", _EPS, W)
        trv = np.trace(V0, axis1=-2, axis2=-1)
        Minv, _ = _inv3(trv[..., None, None] * _EYE - V0)
        om = w + np.einsum("...ij,...j->...i", Minv, z)
        Om = np.einsum("ikj,...k->...ij", _EPS, om)
        f1, f2 = _rotation_factors(np.einsum("...i,...i->...", om, om))
        Q = _EYE + f1[..., None, None] * Om - f2[..., None, None] * (Om @ Om)
        R = Q @ R0
        V = V0 + L @ V0 - V0 @ Om
        Rt = np.swapaxes(R, -1, -2)
        d = Rt @ D @ R
        tr = np.trace(d, axis1=-2, axis2=-1)[..., None, None]
        S = S0 + 2.0 * self.G * (d - tr / 3.0 * _EYE) + self.K * tr * _EYE
        sigma = R @ S @ Rt
        P = J[..., None, None] * sigma @ np.swapaxes(Finv, -1, -2)
        return P, V, R, S

    def update(
        self, F: np.ndarray, state: dict[str, np.ndarray], *, tangent: bool = False
    ) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray | None]:
        """Return ``P``, the trial state and (optionally) ``∂P/∂F`` at ``F``.

        Parameters
        ----------
        F : (n, 3, 3) array_like
            Trial deformation gradient.
        state : dict of str -> ndarray
            Committed state (:meth:`initial_state` or a committed trial state).
        tangent : bool
            Whether to return ``dPdF[g, i, j, k, l] = ∂P_ij/∂F_kl`` (complex step).

        Returns
        -------
        P : (n, 3, 3) ndarray
            First Piola–Kirchhoff stress ``J σ F⁻ᵀ``.
        state : dict of str -> ndarray
            Trial ``F``, ``V``, ``R``, ``S``.
        dPdF : (n, 3, 3, 3, 3) ndarray or None
        """
        F = np.asarray(F, dtype=float)
        if F.ndim != 3 or F.shape[1:] != (3, 3):
            raise ShapeError(f"F must have shape (n, 3, 3), got {F.shape}")
        missing = [k for k in ("F", "V", "R", "S") if k not in state]
        if missing:
            raise InputError(
                f"state must hold F, V, R and S (Hypoelastic.initial_state), missing {missing}"
            )
        F0, V0, R0, S0 = (np.asarray(state[k], dtype=float) for k in ("F", "V", "R", "S"))
        for k, a in zip("FVRS", (F0, V0, R0, S0), strict=True):
            if a.shape != F.shape:
                raise ShapeError(f"state[{k!r}] must have the shape of F {F.shape}, got {a.shape}")
        P, V, R, S = self._step(F, F0, V0, R0, S0)
        trial = {"F": F.copy(), "V": V, "R": R, "S": S}
        if not tangent:
            return P, trial, None
        # the nine directions E_kl at once: F + i h E_kl, shape (n, 9, 3, 3)
        E = np.eye(9).reshape(9, 3, 3)
        Fc = F[:, None] + 1j * _H * E[None]
        Pc = self._step(Fc, F0[:, None], V0[:, None], R0[:, None], S0[:, None])[0]
        A = np.moveaxis(Pc.imag / _H, 1, -1).reshape(F.shape[0], 3, 3, 3, 3)
        return P, trial, A

    def piola(self, F: np.ndarray, state: dict[str, np.ndarray]) -> np.ndarray:
        """Return ``P`` alone (a force-only evaluation).

        Parameters
        ----------
        F : (n, 3, 3) array_like
            Trial deformation gradient.
        state : dict of str -> ndarray
            Committed state.

        Returns
        -------
        (n, 3, 3) ndarray
        """
        return self.update(F, state)[0]

    def describe(self) -> dict[str, Any]:
        """Return the material's constants.

        Returns
        -------
        dict
            ``{'material': 'Hypoelastic', 'K': K, 'G': G}``.
        """
        return {"material": "Hypoelastic", "K": self.K, "G": self.G}
