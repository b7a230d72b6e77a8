"""ScannedString: scanned synthesis after Verplank, Mathews and Shaw (thesis "scanned synthesis
models (technology)", figure 47).

The thesis' three steps, one per part of this module:

1. a spring system — ``n_masses`` masses on a line (fixed ends) or a ring, each pulled to
   its neighbours (``stiffness``), to rest (``centring``) and slowed by ``damping``; the
   vibrational modes sit below ~10–15 Hz so they live at "haptic or gestural" time scales;
2. forces applied to it — a pluck (initial shape), a hammer strike (initial velocity), note
   events, and pushes from a creature's body (:mod:`audio.coupling`);
3. the shape is *scanned* repeatedly along a trajectory at audio rate; the scan frequency
   is the pitch, the shape is the timbre — band-limited: a note whose shape has harmonics
   above the output's band reads the shape without them (:mod:`audio.bandlimit`).

The names follow Csound's ``scanu``/``scans`` where they agree: ``haptic_rate`` is
``1/irate``, ``mass``/``stiffness``/``centring``/``damping`` are ``kmass``/``kstif``/
``kcentr``/``kdamp`` (scalars here; Csound also takes per-node tables), :meth:`pluck` is
``init``/``scanhammer``, :meth:`strike` is ``ifnvel``, and ``trajectory`` is ``ifntraj``.
Like ``scans`` (which interpolates between the last two ``scanu`` shapes) the scanner
interpolates linearly between successive haptic frames as well as between nodes along
the trajectory, so a 500 Hz physics rate makes no zipper noise at 48 kHz;
``interpolation = "none"`` reads the nearest node of the current frame instead, as Csound's
``scantable`` does (:data:`INTERPOLATIONS`).

The physics is semi-implicit (symplectic) Euler at step ``h = 1/haptic_rate``::

    v ← (1 − γh) v + h (k/m · Δx − c/m · x + f/m)        γ = damping / mass
    x ← x + h v

Per mode of angular frequency ω this is stable iff ``0 ≤ γh < 2`` and
``(ωh)² < 4 − 2γh``. The highest mode of the chain has ``ω² ≤ (4k + c)/m`` (the
discrete Laplacian's eigenvalues lie in [0, 4]), so :class:`StringParameters` rejects
``h²(4k + c)/m ≥ 4 − 2γh`` with a message naming the largest stable stiffness.

Why numba over samples: measured in ``bench/voice.py`` (``python -m bench voice``), the
per-sample kernel runs 17–50× faster (e.g. 843 vs 18 real-time voices in one run) than the
same model vectorised in numpy over masses and samples with a Python loop over haptic
frames: a 128-mass step is too small for numpy's per-call overhead to pay off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numba
import numpy as np

from audio.bandlimit import band_limit, dft_basis, harmonics, kept_harmonics

#: Highest mode the thesis allows for gestural control ("lower than 10-15Hz").
GESTURAL_LIMIT_HZ = 15.0

INTERPOLATIONS = ("linear", "none")
"""How the scanner reads the shape: ``linear`` between nodes along the trajectory and between
the last two haptic frames (as Csound's ``scans``: no zipper noise), or ``none``, the node under
the scan position in the current frame (as Csound's ``scantable``: brighter, with the steps of
the frame rate in it)."""


class UnstableStringError(ValueError):
    """String parameters for which the explicit haptic integrator would blow up."""


@dataclass(frozen=True)
class StringParameters:
    """Physical constants of a :class:`ScannedString` (checked for stability on creation).

    ``mass`` is per node; ``stiffness`` (between neighbours) and ``centring`` (to rest) are
    forces per unit displacement, ``damping`` a force per unit velocity. The defaults put
    the highest mode near 9 Hz, inside the thesis' gestural band (:data:`GESTURAL_LIMIT_HZ`).
    A single mass is a string too: between the fixed ends a damped oscillator (ω² = (2k + c)/m,
    inside the bound), scanned as a pulse wave it ring-modulates; on a ring it is its own
    neighbour, so its spring pulls on nothing and only centring rings it (Csound's 1-point
    ``scantable`` is that ring without centring).
    """

    n_masses: int = 128
    mass: float = 1.0
    stiffness: float = 800.0
    centring: float = 4.0
    damping: float = 0.5
    ring: bool = False
    haptic_rate: float = 500.0
    interpolation: str = "linear"

    def __post_init__(self) -> None:
        if self.interpolation not in INTERPOLATIONS:
            raise UnstableStringError(f"interpolation must be one of {INTERPOLATIONS}, got {self.interpolation!r}")
        if self.n_masses < 1:
            raise UnstableStringError(f"a string needs at least 1 mass, got n_masses={self.n_masses}")
        for name in ("mass", "haptic_rate"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise UnstableStringError(f"{name} must be a positive finite number, got {value!r}")
        for name in ("stiffness", "centring", "damping"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise UnstableStringError(f"{name} must be ≥ 0 and finite, got {value!r}")
        h = 1.0 / self.haptic_rate
        gamma_h = self.damping / self.mass * h
        if gamma_h >= 2.0:
            raise UnstableStringError(
                f"damping/mass × step = {gamma_h:.3g} ≥ 2: the explicit integrator oscillates "
                f"and grows; use damping < {2.0 * self.mass * self.haptic_rate:.4g} or raise haptic_rate"
            )
        bound = 4.0 - 2.0 * gamma_h
        omega_h_sq = h * h * (4.0 * self.stiffness + self.centring) / self.mass
        if omega_h_sq >= bound:
            max_stiffness = (bound * self.mass / (h * h) - self.centring) / 4.0
            raise UnstableStringError(
                f"unstable string: h²(4·stiffness + centring)/mass = {omega_h_sq:.4g} must be "
                f"< 4 − 2·damping·h/mass = {bound:.4g} (h = 1/haptic_rate = {h:.4g} s); "
                f"use stiffness < {max(max_stiffness, 0.0):.4g}, a larger mass, or a higher haptic_rate"
            )

    @property
    def highest_mode_hz(self) -> float:
        """Upper bound on the chain's highest natural frequency (Hz), ignoring damping."""
        return math.sqrt((4.0 * self.stiffness + self.centring) / self.mass) / (2.0 * math.pi)

    def retuned(self, tension: float, damping: float) -> "StringParameters":
        """These strings with stiffness × ``tension`` and damping × ``damping`` (a performer's
        or a skill's hand on the string), held within what a config may ask for: no mode above
        :data:`GESTURAL_LIMIT_HZ` (or this string's own highest, if it was set above), and a
        stable integrator (damping, then stiffness, kept a hundredth inside their bounds)."""
        h = 1.0 / self.haptic_rate
        cap = max(self.stiffness_for_highest_mode(GESTURAL_LIMIT_HZ), self.stiffness)
        stiffness = min(max(self.stiffness * tension, 0.0), cap)
        omega_h_sq = h * h * (4.0 * stiffness + self.centring) / self.mass
        most = 0.99 * self.mass * min(4.0 - omega_h_sq, 4.0) / (2.0 * h)  # bound 4 − 2γh above ω²h², γh < 2
        return replace(self, stiffness=stiffness, damping=min(max(self.damping * damping, 0.0), max(most, 0.0)))

    def stiffness_for_highest_mode(self, hz: float) -> float:
        """The stiffness that would put :attr:`highest_mode_hz` at ``hz`` with this mass and
        centring: the most a config may ask for and stay gestural. Negative when centring
        alone already rings faster than ``hz``."""
        return ((2.0 * math.pi * hz) ** 2 * self.mass - self.centring) / 4.0


@numba.njit(cache=True, fastmath=False)
def _haptic_step(x, v, force, ring, k, c, gamma, inv_m, h):
    """One symplectic-Euler step of the whole chain (fixed ends are 0 beyond the ends)."""
    n = x.shape[0]
    for i in range(n):
        left = x[i - 1] if i > 0 else (x[n - 1] if ring else 0.0)
        right = x[i + 1] if i < n - 1 else (x[0] if ring else 0.0)
        accel = inv_m * (k * (left - 2.0 * x[i] + right) - c * x[i] + force[i])
        v[i] = (1.0 - gamma * h) * v[i] + h * accel
    for i in range(n):
        x[i] += h * v[i]


@numba.njit(cache=True, fastmath=False, inline="always")
def _scan_body(out, x, v, x_prev, force, trajectory, state, ring, k, c, gamma, inv_m, h,
               haptic_per_sample, phase_per_sample, dc_pole, interpolate, limited, table, table_prev, basis, first,
               stop, keep, scratch):
    """Fill ``out`` by scanning the chain; run a haptic step whenever a frame is due.

    ``state`` = [scan phase (0..1), haptic fraction (0..1), dc-blocker x₁, dc-blocker y₁, …].
    The value at trajectory position ``p`` is the node shape interpolated linearly along
    the trajectory and between the previous and current haptic frames, or (``interpolate``
    false) the current frame's node at ``int(p)``. ``limited`` (a constant of each caller, so
    the other's branches compile away) scans band-limited (:mod:`audio.bandlimit`): it reads,
    the same way, ``table`` and ``table_prev``, the current and previous frames read along the
    trajectory and projected on harmonics ``first…stop`` of ``basis``.
    """
    n_points = trajectory.shape[0]
    n = x.shape[0]
    if limited:  # the frames as they are now: a pluck or a write to x since the last block is heard
        band_limit(table_prev, x_prev, trajectory, basis, first, stop, keep, scratch)
        band_limit(table, x, trajectory, basis, first, stop, keep, scratch)
    phase, frac, dc_x1, dc_y1 = state[0], state[1], state[2], state[3]
    for s in range(out.shape[0]):
        frac += haptic_per_sample
        if frac >= 1.0:
            frac -= 1.0
            for i in range(n):
                x_prev[i] = x[i]
            _haptic_step(x, v, force, ring, k, c, gamma, inv_m, h)
            if limited:
                table_prev[:] = table
                band_limit(table, x, trajectory, basis, first, stop, keep, scratch)
        pos = phase * n_points
        j = int(pos)
        a = pos - j
        j0 = trajectory[j % n_points]
        j1 = trajectory[(j + 1) % n_points]
        y0 = 0.0
        y1 = 0.0
        if limited:  # the projected tables, read point by point
            t0, t1 = j % n_points, (j + 1) % n_points
            y0 = table_prev[t0] + frac * (table[t0] - table_prev[t0])
            y1 = table_prev[t1] + frac * (table[t1] - table_prev[t1])
            y = y0 + a * (y1 - y0)
        elif not interpolate:
            y = x[j0] if j0 >= 0 else 0.0
        else:
            if j0 >= 0:
                y0 = x_prev[j0] + frac * (x[j0] - x_prev[j0])
            if j1 >= 0:
                y1 = x_prev[j1] + frac * (x[j1] - x_prev[j1])
            y = y0 + a * (y1 - y0)
        dc_y1 = y - dc_x1 + dc_pole * dc_y1  # one-pole DC blocker: a pluck is mostly one-signed
        dc_x1 = y
        out[s] = dc_y1
        phase += phase_per_sample
        phase -= math.floor(phase)
    state[0], state[1], state[2], state[3] = phase, frac, dc_x1, dc_y1


@numba.njit(cache=True, fastmath=False)
def _scan(out, x, v, x_prev, force, trajectory, state, ring, k, c, gamma, inv_m, h,
          haptic_per_sample, phase_per_sample, dc_pole, interpolate):
    """:func:`_scan_body` reading the shape itself (a note with nothing above the band)."""
    _scan_body(out, x, v, x_prev, force, trajectory, state, ring, k, c, gamma, inv_m, h, haptic_per_sample,
               phase_per_sample, dc_pole, interpolate, False, out[:0], out[:0], np.empty((2, 0, 0)), 0, 0, True,
               np.empty((5, 0)))


@numba.njit(cache=True, fastmath=False)
def _scan_band_limited(out, x, v, x_prev, force, trajectory, state, ring, k, c, gamma, inv_m, h,
                       haptic_per_sample, phase_per_sample, dc_pole, table, table_prev, basis, first, stop, keep,
                       scratch):
    """:func:`_scan_body` reading the shape band-limited (linear interpolation only)."""
    _scan_body(out, x, v, x_prev, force, trajectory, state, ring, k, c, gamma, inv_m, h, haptic_per_sample,
               phase_per_sample, dc_pole, True, True, table, table_prev, basis, first, stop, keep, scratch)


@numba.njit(cache=True)
def _limit(signal, gain, out):
    for i in range(signal.shape[0]):
        y = gain * signal[i]
        out[i] = math.tanh(y) if math.isfinite(y) else (math.copysign(1.0, y) if math.isinf(y) else 0.0)


def soft_limit(signal: np.ndarray, *, gain: float = 1.0, out: np.ndarray | None = None) -> np.ndarray:
    """Soft limiter ``tanh(gain · x)``: finite values land strictly inside (−1, 1), ±inf at ±1,
    NaN (which a stable string never produces) at 0. ``out`` may be ``signal`` itself."""
    signal = np.asarray(signal, dtype=float)
    out = np.empty_like(signal) if out is None else out
    _limit(signal.reshape(-1), float(gain), out.reshape(-1))
    return out


def default_trajectory(n_masses: int, *, ring: bool) -> np.ndarray:
    """Scan path over node indices: a ring is read round; a string end to end via its fixed ends.

    ``-1`` stands for a fixed end (displacement 0), so a string's scan wraps without a jump.
    """
    nodes = np.arange(n_masses, dtype=np.int64)
    return nodes if ring else np.concatenate([[-1], nodes])


class ScannedString:
    """A haptic-rate spring chain read at audio rate (thesis figure 47).

    Parameters
    ----------
    parameters : StringParameters
        Physical constants (already checked for stability).
    sample_rate : float
        Audio rate of :meth:`render`.
    frequency : float
        Scan frequency in Hz — the pitch.
    gain : float
        Output gain before the soft limiter.
    trajectory : array of node indices, optional
        Scan path (``-1`` = a fixed end); defaults to :func:`default_trajectory`.

    Example
    -------
    >>> s = ScannedString(StringParameters(), sample_rate=48000, frequency=220.0)
    >>> s.pluck(position=0.3, width=0.1, amplitude=1.0)
    >>> block = s.render(512)
    """

    def __init__(
        self,
        parameters: StringParameters | None = None,
        *,
        sample_rate: float = 48000.0,
        frequency: float = 220.0,
        gain: float = 1.0,
        trajectory: np.ndarray | None = None,
    ) -> None:
        self.parameters = parameters or StringParameters()
        if not (math.isfinite(sample_rate) and sample_rate >= self.parameters.haptic_rate):
            raise ValueError(
                f"sample_rate {sample_rate!r} must be finite and ≥ haptic_rate {self.parameters.haptic_rate}"
            )
        n = self.parameters.n_masses
        self.sample_rate = float(sample_rate)
        self._state = np.zeros(5)  # scan phase, haptic fraction, DC blocker x₁ and y₁, scan increment
        self._band: tuple[float, tuple[int, int, bool]] = (math.nan, (0, 0, True))  # increment → harmonics
        self.frequency = frequency
        self.gain = float(gain)
        traj = default_trajectory(n, ring=self.parameters.ring) if trajectory is None else np.asarray(trajectory, dtype=np.int64)
        if traj.ndim != 1 or len(traj) < 1 or traj.max() >= n or traj.min() < -1:
            raise ValueError(f"trajectory must be a 1-D path of node indices in [-1, {n - 1}], got shape {traj.shape}")
        self.trajectory = traj
        self._tables = np.zeros((2, len(traj)))  # band-limited frame and previous frame
        self._scratch = np.zeros((5, len(traj)))  # their projection's work space
        self.x = np.zeros(n)
        self.v = np.zeros(n)
        self._x_prev = np.zeros(n)
        self.force = np.zeros(n)
        self.dc_pole = math.exp(-2.0 * math.pi * 10.0 / self.sample_rate)
        self.resets = 0

    def bind(self, x: np.ndarray, v: np.ndarray, x_prev: np.ndarray, force: np.ndarray, state: np.ndarray) -> None:
        """Keep this string's state in the given arrays from now on (rows of a
        :class:`~audio.string_bank.StringBank`, whose kernel renders many strings at once)."""
        for new, old in zip((x, v, x_prev, force, state), (self.x, self.v, self._x_prev, self.force, self._state)):
            new[:] = old
        self.x, self.v, self._x_prev, self.force, self._state = x, v, x_prev, force, state

    @property
    def frequency(self) -> float:
        return self._frequency

    @frequency.setter
    def frequency(self, hz: float) -> None:
        if not (math.isfinite(hz) and 0.0 <= hz < 0.5 * self.sample_rate):
            raise ValueError(f"scan frequency must be in [0, Nyquist), got {hz!r}")
        self._frequency = float(hz)
        self._state[4] = self._frequency / self.sample_rate

    def _bump(self, position: float, width: float) -> np.ndarray:
        """A raised cosine ``width`` wide at ``position`` along the string, at the masses. One
        narrower than two spacings of the masses is widened to two: else it could fall between
        them and move none (a note on a string of 1–3 masses plucked nothing and sang silence)."""
        if not (0.0 <= position <= 1.0 and 0.0 < width <= 1.0):
            raise ValueError(f"position must be in [0, 1] and width in (0, 1], got {position!r}, {width!r}")
        n = self.parameters.n_masses
        width = max(width, 2.0 / max(n - 1, 1))
        u = np.linspace(0.0, 1.0, n)
        d = np.abs(u - position)
        if self.parameters.ring:
            d = np.minimum(d, 1.0 - d)
        return np.where(d < width / 2, 0.5 * (1.0 + np.cos(2.0 * np.pi * d / width)), 0.0)

    def pluck(self, *, position: float = 0.3, width: float = 0.2, amplitude: float = 1.0) -> None:
        """Add a raised-cosine displacement (an initial shape; Csound's ``scanhammer``)."""
        _check_finite("amplitude", amplitude)
        self.x += amplitude * self._bump(position, width)
        self._x_prev[:] = self.x

    def strike(self, *, position: float = 0.3, width: float = 0.1, velocity: float = 10.0) -> None:
        """Add a raised-cosine velocity: a hammer blow (Csound's ``ifnvel``)."""
        _check_finite("velocity", velocity)
        self.v += velocity * self._bump(position, width)

    def note_on(self, frequency: float, velocity: float = 1.0, *, position: float = 0.3) -> None:
        """A note event: set the scan frequency and pluck with amplitude ``velocity``."""
        self.frequency = frequency
        self.pluck(position=position, amplitude=velocity)

    def push(self, force: np.ndarray) -> None:
        """Set the external per-node force held until the next push (e.g. from the body)."""
        force = np.asarray(force, dtype=float)
        if force.shape != self.force.shape:
            raise ValueError(f"force must have shape {self.force.shape}, got {force.shape}")
        self.force[:] = np.nan_to_num(force, nan=0.0, posinf=0.0, neginf=0.0)

    def silence(self) -> None:
        """Bring the string to rest (shape, velocity, DC blocker)."""
        for array in (self.x, self.v, self._x_prev, self._state[2:4]):
            array[:] = 0.0

    def energy(self) -> float:
        """Mechanical energy (kinetic + springs + centring): what damping takes away."""
        p = self.parameters
        ends = (self.x, np.roll(self.x, -1)) if p.ring else (np.r_[0.0, self.x], np.r_[self.x, 0.0])
        stretch = ends[1] - ends[0]
        return float(0.5 * (p.mass * self.v @ self.v + p.stiffness * stretch @ stretch + p.centring * self.x @ self.x))

    def band(self) -> tuple[int, int, bool]:
        """The harmonics this string's scan is projected on at its frequency
        (:func:`~audio.bandlimit.harmonics`): ``first == stop`` when none of its shape lies above
        the band, or the reading is ``"none"`` (not band-limited)."""
        increment = self._state[4]  # the bank may move a note here without the setter (a stolen voice)
        if increment != self._band[0]:
            first, stop, keep = harmonics(kept_harmonics(increment), len(self.trajectory))
            linear = self.parameters.interpolation == "linear"
            self._band = (increment, (int(first), int(stop), bool(keep)) if linear else (0, 0, True))
        return self._band[1]

    def render_raw(self, out: np.ndarray) -> np.ndarray:
        """Scan ``len(out)`` samples into ``out`` (no gain, no limiter); advances the physics.
        Band-limited (:mod:`audio.bandlimit`) when the note has harmonics above the band and fewer
        than :data:`~audio.bandlimit.FULL_BAND` in it."""
        p = self.parameters
        first, stop, keep = self.band()
        args = (out, self.x, self.v, self._x_prev, self.force, self.trajectory, self._state, p.ring, p.stiffness,
                p.centring, p.damping / p.mass, 1.0 / p.mass, 1.0 / p.haptic_rate, p.haptic_rate / self.sample_rate,
                self._state[4], self.dc_pole)
        if first < stop:
            _scan_band_limited(*args, *self._tables, dft_basis(len(self.trajectory)), first, stop, keep, self._scratch)
        else:
            _scan(*args, p.interpolation == "linear")
        if not math.isfinite(self.x.sum() + self._state[3]):
            self.silence()  # only reachable by forces of ~1e300: restart quiet rather than NaN
            out[:] = 0.0
            self.resets += 1
        return out

    def render(self, frames: int, *, out: np.ndarray | None = None) -> np.ndarray:
        """``frames`` samples of audio in [−1, 1]: scanned, gained, soft-limited."""
        out = np.empty(frames) if out is None else out[:frames]
        return soft_limit(self.render_raw(out), gain=self.gain, out=out)


def _check_finite(name: str, value: float) -> None:
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
