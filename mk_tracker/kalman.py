"""Constant-velocity Kalman filter of an object centroid (Schizas et al. 2018, Secs. 2 and 4).

State ``s = (cx, cy, vx, vy)``: the centroid in pixels and its velocity in pixels per
second.  The motion model is (2.1) ``s(t) = A s(t-1) + u(t)`` with the transition matrix
(2.2) and the process-noise covariance (2.3) of a continuous white-noise acceleration of
spectral density ``sigma_u**2``.  The measurement is the estimated centroid (4.1)
``c = H s + w`` with ``H = [I_2 0]`` and ``w ~ (0, sigma_w**2 I_2)``.

``dt`` (the paper's Delta T) is always passed in seconds by the caller, computed from frame
time stamps; it is never assumed to be one frame.  Hence ``sigma_u`` is in px / s^1.5 and the
velocity in px / s.

The module is shared by the thermal detector (Algorithm 2, one filter per object) and the
multi-object tracker.  Everything is pure numpy; bad input raises :class:`KalmanError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from mk_tracker.parameters import parameter, validate_config

#: Measurement matrix H of (4.1): the filter observes the centroid only.
MEASUREMENT_MATRIX = np.array([[1.0, 0.0, 0.0, 0.0],
                               [0.0, 1.0, 0.0, 0.0]])


class KalmanError(ValueError):
    """A time step, measurement or noise level the filter cannot use."""


@dataclass(frozen=True)
class KalmanConfig:
    """Noise levels of the constant-velocity model.

    The paper gives no value of ``sigma_u`` (it asks that ``3 sigma_u`` be "a small number of
    pixels" per frame); 30 px/s^1.5 lets a walking person's velocity change by ~5 px/s per
    frame at 30 Hz.  For ``sigma_w`` it reports "less than 3 pixels"; 2 px is the default.
    """

    sigma_u: float = parameter(30.0, "Process noise std (2.3): white acceleration spectral "
                               "density, px/s^1.5", minimum=0.0, maximum=1e6)
    sigma_w: float = parameter(2.0, "Measurement noise std (4.1) of the centroid, px",
                               minimum=1e-6, maximum=1e6)
    initial_position_var: float = parameter(4.0, "Initial variance of the centroid, px^2",
                                            minimum=1e-9, maximum=1e12)
    initial_velocity_var: float = parameter(2500.0, "Initial variance of the velocity, "
                                            "(px/s)^2", minimum=1e-9, maximum=1e12)


def _check_dt(dt: float) -> float:
    try:
        value = float(dt)
    except (TypeError, ValueError) as exc:
        raise KalmanError(f"time step {dt!r} is not a number") from exc
    if not math.isfinite(value) or value <= 0.0:
        raise KalmanError(f"time step must be a positive finite number of seconds, got {dt!r}")
    return value


def _check_std(name: str, value: float, *, allow_zero: bool) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise KalmanError(f"{name} {value!r} is not a number") from exc
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        raise KalmanError(f"{name} must be a finite {'non-negative' if allow_zero else 'positive'}"
                          f" number, got {value!r}")
    return v


def _as_point(name: str, value: Sequence[float]) -> np.ndarray:
    if type(value) is tuple and len(value) == 2 and type(value[0]) is float \
            and type(value[1]) is float:
        # the common case (a centroid tuple), without numpy's generic conversion
        if not (math.isfinite(value[0]) and math.isfinite(value[1])):
            raise KalmanError(f"{name} {list(value)} has a NaN or infinite value")
        return np.array(value)
    try:
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise KalmanError(f"{name} {value!r} is not two numbers") from exc
    if arr.shape != (2,):
        raise KalmanError(f"{name} must have two values (x, y), got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise KalmanError(f"{name} {arr.tolist()} has a NaN or infinite value")
    return arr


def transition_matrix(dt: float) -> np.ndarray:
    """State transition matrix A of (2.2) for a step of ``dt`` seconds."""
    dt = _check_dt(dt)
    a = np.eye(4)
    a[0, 2] = dt
    a[1, 3] = dt
    return a


def process_noise(dt: float, sigma_u: float) -> np.ndarray:
    """Process-noise covariance Sigma_u of (2.3) for a step of ``dt`` seconds.

    ``sigma_u**2 * [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]]``.
    """
    dt = _check_dt(dt)
    s2 = _check_std("sigma_u", sigma_u, allow_zero=True) ** 2
    a, b, c = s2 * dt ** 3 / 3.0, s2 * dt ** 2 / 2.0, s2 * dt
    return np.array([[a, 0.0, b, 0.0], [0.0, a, 0.0, b], [b, 0.0, c, 0.0], [0.0, b, 0.0, c]])


def _positive_semidefinite(cov: np.ndarray) -> np.ndarray:
    """``cov`` itself when no variance is negative, else its nearest positive semi-definite
    matrix (negative eigenvalues set to 0).

    In exact arithmetic (4.3) and the Joseph form of (4.4) keep P positive semi-definite.
    In double precision they cannot when P spans more than ~16 decades: with an initial
    position variance 1e-9, velocity variance 1e12, ``sigma_u = 0``, ``sigma_w = 1e-6`` and a
    4.75 s step, the posterior velocity variance is 4.4e-17 but ``A P A^T`` has entries of
    2e13 whose rounding (~1e-3) left it at -1.2e-4 (a property test found it).  Such a
    result is rounding noise around a singular matrix; clipping its negative eigenvalues
    changes P by about that noise, and each variance becomes a sum of non-negative terms.
    """
    # the usual case, checked on Python floats (this runs on every predict and update); a
    # NaN fails ``>=`` and falls to the finiteness test: a non-finite P is the caller's error
    if min(cov.ravel()[::5].tolist()) >= 0.0 or not np.all(np.isfinite(cov)):
        return cov
    values, vectors = np.linalg.eigh(cov)
    out = (vectors * np.maximum(values, 0.0)) @ vectors.T
    return 0.5 * (out + out.T)


#: ``(dt, sigma_u) -> (A, Sigma_u)`` of recent steps: every object of a frame is predicted
#: over the same ``dt``.  Read-only arrays; bounded.
_STEP_MATRICES: dict = {}


def _step_matrices(dt: float, sigma_u: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`transition_matrix` and :func:`process_noise` of a step, cached."""
    key = (dt, sigma_u)
    hit = _STEP_MATRICES.get(key)
    if hit is None:
        a = transition_matrix(dt)
        q = process_noise(dt, sigma_u)
        a.setflags(write=False)
        q.setflags(write=False)
        if len(_STEP_MATRICES) >= 16:
            _STEP_MATRICES.clear()
        hit = _STEP_MATRICES[key] = (a, q)
    return hit


class ConstantVelocityKalman:
    """Kalman filter of one centroid with the model (2.1)-(2.3), (4.1)-(4.5).

    ``state`` is ``(cx, cy, vx, vy)`` and ``covariance`` its 4x4 error covariance P(t|t)
    (or P(t|t-1) right after :meth:`predict`).  Noise levels default to
    :class:`KalmanConfig`; :meth:`from_config` builds a filter from a config.
    """

    def __init__(self, center: Sequence[float], *, sigma_u: float | None = None,
                 sigma_w: float | None = None, initial_velocity: Sequence[float] = (0.0, 0.0),
                 initial_position_var: float | None = None,
                 initial_velocity_var: float | None = None) -> None:
        d = KalmanConfig()
        self.sigma_u = _check_std("sigma_u", d.sigma_u if sigma_u is None else sigma_u,
                                  allow_zero=True)
        self.sigma_w = _check_std("sigma_w", d.sigma_w if sigma_w is None else sigma_w,
                                  allow_zero=False)
        pos_var = _check_std("initial_position_var", d.initial_position_var
                             if initial_position_var is None else initial_position_var,
                             allow_zero=False)
        vel_var = _check_std("initial_velocity_var", d.initial_velocity_var
                             if initial_velocity_var is None else initial_velocity_var,
                             allow_zero=False)
        c = _as_point("center", center)
        v = _as_point("initial_velocity", initial_velocity)
        self._state = np.concatenate([c, v])
        self._cov = np.diag([pos_var, pos_var, vel_var, vel_var])

    @classmethod
    def from_config(cls, center: Sequence[float], config: KalmanConfig,
                    initial_velocity: Sequence[float] = (0.0, 0.0)) -> "ConstantVelocityKalman":
        """A filter at ``center`` with the noise levels of ``config`` (validated)."""
        validate_config(config)
        return cls(center, sigma_u=config.sigma_u, sigma_w=config.sigma_w,
                   initial_velocity=initial_velocity,
                   initial_position_var=config.initial_position_var,
                   initial_velocity_var=config.initial_velocity_var)

    @property
    def state(self) -> np.ndarray:
        """A copy of the state ``(cx, cy, vx, vy)``."""
        return self._state.copy()

    @property
    def covariance(self) -> np.ndarray:
        """A copy of the 4x4 error covariance."""
        return self._cov.copy()

    @property
    def center(self) -> np.ndarray:
        """Estimated centroid ``(cx, cy)``."""
        return self._state[:2].copy()

    @property
    def velocity(self) -> np.ndarray:
        """Estimated velocity ``(vx, vy)`` in px/s."""
        return self._state[2:].copy()

    def predicted(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """``(s(t|t-1), P(t|t-1))`` after ``dt`` seconds, without changing the filter.

        (4.2): ``s(t|t-1) = A s(t-1|t-1)``.  (4.3): ``P(t|t-1) = A P(t-1|t-1) A^T + Sigma_u``;
        the paper prints ``F^T`` in (4.3), a typo for ``A^T`` (F is its frame symbol).
        """
        a, q = _step_matrices(dt, self.sigma_u)
        state = a @ self._state
        cov = a @ self._cov @ a.T + q
        return state, _positive_semidefinite(0.5 * (cov + cov.T))

    def predict(self, dt: float) -> np.ndarray:
        """Advance the filter by ``dt`` seconds, (4.2)-(4.3); returns the predicted state."""
        self._state, self._cov = self.predicted(dt)
        return self._state.copy()

    def warp(self, linear: np.ndarray, translation: Sequence[float]) -> None:
        """Move the filter into another image's pixel grid: ``x' = L x + t`` (camera motion).

        A point ``x`` of the old image is at ``L x + t`` in the new one (``L`` 2x2, ``t``
        2-vector; BoT-SORT, Aharon et al. 2022, Sec. 3.2).  The state of (2.1) maps through
        ``T = diag(L, L)`` plus ``(t, 0)``: the centroid moves and turns/scales with the
        image, the velocity only turns/scales (a translation of the image is no motion of the
        person).  The error covariance (the P of (4.3)-(4.4)) is that of a linear map,
        ``P' = T P T^T``.  A non-finite or malformed input raises :class:`KalmanError` and
        leaves the filter unchanged.
        """
        try:
            lin = np.asarray(linear, dtype=np.float64).reshape(2, 2)
            shift = np.asarray(translation, dtype=np.float64).reshape(2)
        except (TypeError, ValueError) as exc:
            raise KalmanError(f"warp needs a 2x2 matrix and a 2-vector, got {linear!r}, "
                              f"{translation!r}") from exc
        if not (np.all(np.isfinite(lin)) and np.all(np.isfinite(shift))):
            raise KalmanError("warp has a NaN or infinite value; filter left unchanged")
        t = np.zeros((4, 4))
        t[:2, :2] = lin
        t[2:, 2:] = lin
        state = t @ self._state
        state[:2] += shift
        cov = t @ self._cov @ t.T
        self._state = state
        self._cov = _positive_semidefinite(0.5 * (cov + cov.T))

    def _measurement_std(self, sigma_w: float | None) -> float:
        if sigma_w is None:
            return self.sigma_w
        return _check_std("sigma_w", sigma_w, allow_zero=False)

    def innovation_covariance(self, sigma_w: float | None = None) -> np.ndarray:
        """``H P H^T + sigma_w^2 I``, the bracket of (4.5)."""
        r = self._measurement_std(sigma_w) ** 2
        return self._cov[:2, :2] + r * np.eye(2)

    def innovation_distance(self, measurement: Sequence[float],
                            sigma_w: float | None = None) -> float:
        """Squared Mahalanobis distance of ``measurement`` from the current ``H s``.

        Chi-square with two degrees of freedom under the model (4.1), usable for gating
        (e.g. 9.21 for 99%).  Call it after :meth:`predict`.
        """
        z = _as_point("measurement", measurement)
        nu = z - self._state[:2]
        s = self.innovation_covariance(sigma_w)
        return float(nu @ np.linalg.solve(s, nu))

    def update(self, measurement: Sequence[float], sigma_w: float | None = None) -> np.ndarray:
        """Correct the state with a measured centroid, (4.4)-(4.5); returns the new state.

        ``sigma_w`` overrides the measurement std for this call only (the tracker makes it
        follow the match quality).  A NaN or malformed measurement raises
        :class:`KalmanError` and leaves the filter unchanged.
        """
        z = _as_point("measurement", measurement)
        r = self._measurement_std(sigma_w) ** 2
        p = self._cov
        # S = H P H^T + sigma_w^2 I (2x2, symmetric), inverted in closed form: this runs for
        # every object of every frame, and np.linalg on a 2x2 costs more than the arithmetic
        s00, s01, s11 = p[0, 0] + r, 0.5 * (p[0, 1] + p[1, 0]), p[1, 1] + r
        det = s00 * s11 - s01 * s01
        if not (math.isfinite(det) and det > 0.0):
            raise KalmanError("innovation covariance is not positive definite; filter left "
                              "unchanged")
        s_inv = np.array([[s11, -s01], [-s01, s00]]) / det
        gain = p[:, :2] @ s_inv                      # (4.5): G = P H^T S^-1
        state = self._state + gain @ (z - self._state[:2])
        # (4.4) is (I - G H) P; in exact arithmetic that equals the Joseph form used here,
        # (I - G H) P (I - G H)^T + G R G^T, which stays positive semi-definite in floating
        # point: with a tiny position and a huge velocity variance (1e-9, 1e12) the short
        # form's velocity variance cancelled to -2.4e-4 (a property test found it)
        a = np.eye(4)
        a[:, :2] -= gain                             # I - G H, with H = [I 0]
        with np.errstate(invalid="ignore", over="ignore"):   # a non-finite result is refused
            cov = a @ p @ a.T + r * (gain @ gain.T)          # just below, with a clear error
        cov = _positive_semidefinite(0.5 * (cov + cov.T))
        if not (math.isfinite(float(state.sum())) and math.isfinite(float(cov.sum()))):
            raise KalmanError("update produced a non-finite state; filter left unchanged")
        self._state, self._cov = state, cov
        return self._state.copy()
