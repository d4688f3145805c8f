"""Linear state-space models of a compiled DAE at an operating point.

At a steady state (``y' = 0``) the DAE ``F(t, y, y', u) = 0`` linearises to::

    J_yp[:, x] dx' + J_y[:, x] dx + J_y[:, z] dz + F_u du = 0

with ``x`` the differential variables (``system.differential``) and ``z`` the algebraic ones.
The compiler guarantees index one, so ``M = [J_yp[:, x], J_y[:, z]]`` is regular and
``[dx'; dz] = -M^-1 (J_y[:, x] dx + F_u du)`` gives ``A, B`` (rows of ``dx'``) and the algebraic
response (rows of ``dz``) from which any named output's ``C, D`` follow.

Loops and python-control
------------------------
A circuit with its own controller linearises to the *closed* loop. When an input enters the
circuit only through a comparator ``e = input - output`` (the PVE's set point and LVDT reading,
say), the loop is opened exactly in the linear model: with ``x' = A x + b e`` and
``e = r - c x`` the closed loop has ``A - b c``, so the open loop is ``A + b c``
(:meth:`LinearModel.open_loop`); :meth:`LinearModel.feedback` closes it again with any gain.
Margins, step metrics and root loci are thin wrappers over python-control
(``control.stability_margins``, ``control.step_info``, ``control.root_locus_map``).

Inputs
------
A compiled system has its parameters folded into the generated code, so an input cannot be
perturbed inside it. Inputs are therefore given either

- directly as residual sensitivities ``dF/du`` (``linearize(system, op, {"u": column}, ...)``),
- or, most conveniently, by a *builder*: :func:`linearize_circuit` takes
  ``build(u: dict) -> Circuit``, compiles ``build(u0)``, finds its steady state and obtains
  ``dF/du`` by central differences of the residuals of ``build(u0 +- du)`` evaluated at that
  same operating point (the systems share their unknowns, since only constants change; this is
  checked).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Callable, Mapping, NamedTuple, Sequence

import numpy as np

from ..errors import ParameterError, PlausibilityWarning, PvgraphError
from ..system import System
from .steady import OperatingPoint, steady_state

__all__ = ["LinearModel", "Margins", "linearize", "linearize_circuit", "input_sensitivity"]

_C_BIG = 2.0 ** 30  # c used to split dF/dy' from dF/dy without cancellation


class Margins(NamedTuple):
    """Gain and phase margins of a loop transfer function (``control.stability_margins``)."""

    gain: float         # gain margin [-] (inf if the phase never reaches -180 deg)
    phase: float        # phase margin [deg]
    w_gain: float       # phase crossover frequency, where the gain margin is read [rad/s]
    w_phase: float      # gain crossover frequency, where the phase margin is read [rad/s]

    @property
    def gain_db(self) -> float:
        """Gain margin [dB]."""
        return float(20.0 * np.log10(self.gain))


@dataclass
class LinearModel:
    """``x' = A x + B u``, ``y = C x + D u`` in deviations from an operating point."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_names: list
    input_names: list
    output_names: list
    op: OperatingPoint | None = None

    def _idx(self, key, names, what):
        if isinstance(key, (bool, np.bool_)):
            raise TypeError(f"{what} {key!r}: give a name or an index, not a bool")
        if isinstance(key, (int, np.integer)):
            if not names:
                raise IndexError(f"the model has no {what}s, so it has no {what} {int(key)} "
                                 f"(linearise with at least one {what})")
            if not -len(names) <= int(key) < len(names):
                raise IndexError(f"{what} index {int(key)} is out of range: the model has "
                                 f"{len(names)} {what}s {names}")
            return int(key) % len(names)
        if not isinstance(key, str):
            raise TypeError(f"{what} {key!r}: give a name or an integer index; the {what}s are "
                            f"{names}")
        if key in names:
            return names.index(key)
        system = self.op.system if self.op is not None else None
        if system is not None and what != "input":   # an exposed name of an output variable
            try:
                real = system.resolve_name(key)
                return [system.resolve_name(n) for n in names].index(real)
            except (KeyError, ValueError):
                pass
        raise KeyError(f"no {what} named {key!r}; the {what}s are {names}")

    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A``, sorted by decreasing real part (the dominant ones first)."""
        ev = np.linalg.eigvals(self.A) if self.A.size else np.zeros(0)
        return ev[np.argsort(-ev.real, kind="stable")]

    def stability(self) -> tuple[str, str]:
        """``(verdict, why)`` of the model's internal stability: ``"stable"`` (every pole in
        the open left half-plane), ``"marginally stable"`` (the others on the imaginary axis,
        each with as many independent modes as its multiplicity: a conserved volume, an
        undamped spring-mass) or ``"unstable"`` (a pole in the right half-plane, or a pole
        on the axis repeated as a chain: a free mass pushed by a force).

        A pole counts as on the axis where its real part is within the rounding of that
        eigenvalue: ``100 eps |A| kappa`` with ``kappa`` its condition number (from its left
        and right eigenvectors), at most ``10 sqrt(eps |A|)`` (a double pole at 0 splits by
        that much): a well-conditioned pole at +0.05 1/s beside poles of 1e8 rad/s is
        unstable.
        """
        import scipy.linalg
        n = self.A.shape[0]
        if n == 0:
            return "stable", "no states"
        w, vl, vr = scipy.linalg.eig(self.A, left=True, right=True)
        eps = np.finfo(float).eps
        size = max(1.0, float(np.linalg.norm(self.A)))
        with np.errstate(divide="ignore", invalid="ignore"):
            kappa = np.linalg.norm(vl, axis=0) * np.linalg.norm(vr, axis=0) / np.abs(
                np.sum(vl.conj() * vr, axis=0))
        tol = np.minimum(100.0 * eps * size * np.nan_to_num(kappa, nan=np.inf, posinf=np.inf),
                         10.0 * math.sqrt(eps * size))
        right = w.real > tol
        if right.any():
            worst = w[right][np.argmax(w[right].real)]
            return "unstable", (f"{int(right.sum())} pole{'s' if right.sum() > 1 else ''} in the "
                                f"right half-plane (largest real part {worst.real:.4g} 1/s)")
        on_axis = np.abs(w.real) <= tol
        if not on_axis.any():
            return "stable", "every pole in the left half-plane"
        axis = w[on_axis]
        seen: list = []
        for q in axis:
            near = max(10.0 * math.sqrt(eps * size), 1e-9 * abs(q))
            if any(abs(q.imag - r.imag) <= near for r in seen):
                continue
            seen.append(q)
            mult = int(np.sum(np.abs(axis.imag - q.imag) <= near))
            sv = np.linalg.svd(self.A - q.imag * 1j * np.eye(n), compute_uv=False)
            modes = int(np.sum(sv <= math.sqrt(eps) * max(1.0, float(sv.max()))))
            if modes < mult:
                return "unstable", (f"the pole {_pole_text(q)} on the imaginary axis is repeated "
                                    f"as a chain ({mult} poles, {modes} independent "
                                    f"mode{'s' if modes != 1 else ''}): an output grows "
                                    f"without bound (a free mass pushed by a force)")
        return "marginally stable", (f"{axis.size} pole{'s' if axis.size > 1 else ''} on the "
                                     f"imaginary axis ({', '.join(_pole_text(q) for q in seen)}"
                                     f"), none repeated as a chain: conserved quantities or "
                                     f"undamped modes")

    def dc_gain(self) -> np.ndarray:
        """Steady-state gain ``G(0) = D - C A^-1 B`` (outputs x inputs).

        With a pole at s = 0 (an integrator: a cylinder position, a shaft angle) ``A`` is
        singular. As python-control's ``dcgain``, the gain is then infinite, but only on the
        paths the integrator lies on (it is excited by the input and seen by the output):
        those entries are ``+inf`` or ``-inf`` (the sign of ``G(s)`` as s -> 0+, the direction
        in which a step makes the output ramp) and a ``RuntimeWarning`` names the integrating
        states; the other entries are their finite limits.
        """
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", RuntimeWarning)
                G = self.D - self.C @ np.linalg.solve(self.A, self.B)
            if np.all(np.isfinite(G)):
                return G
        except (np.linalg.LinAlgError, RuntimeWarning):
            pass
        G, integrators = _dc_gain_singular(self.A, self.B, self.C, self.D, self.state_names)
        if np.isinf(G).any():
            warnings.warn(f"dc_gain: the model has a pole at s = 0 (an integrator in "
                          f"{integrators}); the DC gain is infinite on the paths through it",
                          RuntimeWarning, stacklevel=2)
        return G

    def frequency_response(self, w, output=0, input=0) -> np.ndarray:
        """``G(j w) = C (j w I - A)^-1 B + D`` of the path ``input -> output`` at the angular
        frequencies ``w`` [rad/s] (complex, one per frequency)."""
        i = self._idx(output, self.output_names, "output")
        j = self._idx(input, self.input_names, "input")
        try:
            w = np.atleast_1d(np.asarray(w, dtype=float))
        except (TypeError, ValueError):
            raise ValueError(f"w: frequencies [rad/s] as numbers, got {w!r}") from None
        if w.ndim != 1 or w.size == 0 or not np.all(np.isfinite(w)) or np.any(w < 0.0):
            raise ValueError(f"w: a non-empty 1-D array of finite frequencies >= 0 [rad/s], got "
                             f"shape {w.shape}" + ("" if w.size == 0 else
                                                   f", from {float(w.min()):g} to "
                                                   f"{float(w.max()):g}"))
        A, b, c, d = self.A, self.B[:, j], self.C[i], self.D[i, j]
        eye = np.eye(A.shape[0])
        out = np.empty(w.size, dtype=complex)
        for k, wk in enumerate(w):
            if wk == 0.0:   # a pole at 0 off the path leaves G(0) finite: dc_gain's value
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    out[k] = self.dc_gain()[i, j]
                continue
            out[k] = c @ np.linalg.solve(1j * wk * eye - A, b) + d
        return out

    def bode(self, w, output=0, input=0):
        """``(magnitude [dB], phase [deg])`` of the path ``input -> output`` at ``w`` [rad/s];
        the phase is unwrapped along ``w``."""
        g = self.frequency_response(w, output, input)
        return 20.0 * np.log10(np.abs(g)), np.degrees(np.unwrap(np.angle(g)))

    def tf(self, output=0, input=0):
        """``(num, den)`` of the transfer function from ``input`` to ``output`` (scipy.signal)."""
        from scipy import signal
        i = self._idx(output, self.output_names, "output")
        j = self._idx(input, self.input_names, "input")
        num, den = signal.ss2tf(self.A, self.B, self.C[i:i + 1], self.D[i:i + 1], input=j)
        return num[0], den

    def to_control(self):
        """The model as a python-control ``StateSpace`` (imported lazily).

        python-control forbids '.' in signal names, so dots become '_' there.
        """
        control = _control()
        if not self.input_names or not self.output_names:
            raise PvgraphError(f"to_control: the model has {len(self.input_names)} inputs and "
                               f"{len(self.output_names)} outputs; python-control needs at "
                               f"least one of each")

        def clean(names):
            return [str(nm).replace(".", "_") for nm in names]
        return control.ss(self.A, self.B, self.C, self.D, inputs=clean(self.input_names),
                          outputs=clean(self.output_names), states=clean(self.state_names))

    def siso(self, output=0, input=0):
        """The path from ``input`` to ``output`` as a python-control ``StateSpace``."""
        control = _control()
        i = self._idx(output, self.output_names, "output")
        j = self._idx(input, self.input_names, "input")
        return control.ss(self.A, self.B[:, j:j + 1], self.C[i:i + 1], self.D[i:i + 1, j:j + 1])

    def margins(self, output=0, input=0, *, points_per_decade: int = 200) -> Margins:
        """Gain and phase margins of the path ``input -> output`` taken as a loop transfer
        function (negative unity feedback), with their crossover frequencies.

        ``control.stability_margins`` on the frequency response, sampled from two decades below
        the slowest to two above the fastest pole or zero: a linearised circuit has modes up
        to 1e8 rad/s, whose transfer-function polynomials overflow ``control.margin``'s
        default polynomial method.
        """
        control = _control()
        if not (isinstance(points_per_decade, (int, np.integer)) and points_per_decade >= 1):
            raise ValueError(f"points_per_decade must be a positive integer, got "
                             f"{points_per_decade!r}")
        sys = self.siso(output, input)
        roots = np.concatenate([self.poles(), control.zeros(sys)])
        # a lightly damped resonance (a hydraulic spring: zeta 0.005-0.02) turns its phase by
        # 180 degrees and peaks within a few zeta wn of wn, about one step of the log grid:
        # sampled there densely, so the peak and the crossover are not stepped over (at
        # 200 points per decade a gain margin came out 35 % high at zeta 0.0073)
        extra = _resonance_points(roots)

        def grid(w):
            return np.unique(np.concatenate([w, extra])) if extra.size else w
        w = grid(_frequency_grid(roots, points_per_decade))

        def response(w):
            return np.asarray(control.frequency_response(sys, w).complex).reshape(-1)
        h = response(w)
        # the gain crossover can lie outside two decades of the poles (a high loop gain above
        # them, an integrator's below): widen the grid by two decades at a time until the
        # magnitude is below 1 at the top and, where it rises towards low frequencies, above
        # 1 at the bottom
        for _ in range(MARGIN_GRID_WIDENINGS):
            top, bottom = abs(h[-1]) >= 1.0, abs(h[0]) <= 1.0 and abs(h[0]) > abs(h[1])
            if not (top or bottom):
                break
            lo, hi = np.log10(w[0]) - 2.0 * bottom, np.log10(w[-1]) + 2.0 * top
            w = grid(np.logspace(lo, hi, max(int((hi - lo) * points_per_decade), 2)))
            h = response(w)
        gm, pm, _, wcg, wcp, _ = control.stability_margins(
            (np.abs(h), np.degrees(np.unwrap(np.angle(h))), w))
        return Margins(float(gm), float(pm), float(wcg), float(wcp))

    def step_info(self, output=0, input=0, **options) -> dict:
        """``control.step_info`` of the path ``input -> output`` (rise time 10-90 %, settling
        time to 2 %, overshoot in % of the final value, ...); ``options`` go to it unchanged.

        Unless ``timepts`` is given, the response is computed over ten time constants of the
        slowest stable mode that the step excites (python-control's own horizon follows the
        fast modes of a linearised circuit and can end before a slow one has settled), with
        steps of at most a fiftieth of the fastest such mode's time constant (at least 20000
        steps, at most 500000). A mode whose share of the response is below 1e-4 of its
        largest (a slow leakage pole all but cancelled by a zero) sets neither.
        """
        control = _control()
        known = ("timepts", "timepts_num", "final_output", "params", "SettlingTimeThreshold",
                 "RiseTimeLimits")
        unknown = [k for k in options if k not in known]
        if unknown:
            raise TypeError(f"step_info: unknown option(s) {unknown}; control.step_info takes "
                            f"{', '.join(known)}")
        sys = self.siso(output, input)
        if "final_output" not in options:
            # the path's own final value: where a pole at 0 lies off the path (a conserved
            # volume, a rod position the output does not see) control's C (-A)^-1 B is NaN
            j = self._idx(input, self.input_names, "input")
            i = self._idx(output, self.output_names, "output")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                final = float(self.dc_gain()[i, j])
            if not math.isfinite(final):
                raise PvgraphError(
                    f"step_info: the path {self.input_names[j]} -> {self.output_names[i]} "
                    f"integrates (a pole at s = 0 on it): a step makes the output ramp, so it "
                    f"has no final value to rise to or settle at; use step() for the response")
            options["final_output"] = final
        if "timepts" not in options:
            options["timepts"] = _step_grid(sys.A, sys.B, sys.C)
        else:
            options["timepts"] = _times(options["timepts"], "timepts")
        T = options["timepts"]
        steps = np.diff(T)
        if steps.size and not np.allclose(steps, steps[0], rtol=1e-9, atol=0.0):
            # a grid fine over the fast modes and coarse after (see _step_grid): the response
            # segment by segment (python-control takes evenly spaced times only)
            return control.step_info(_step_response(control, sys, T), **options)
        return control.step_info(sys, **options)

    def damping(self):
        """``(wn, zeta, poles)``: natural frequency ``|p|`` [rad/s] and damping ratio
        ``-Re p / |p|`` of each pole (as ``control.damp``; NaN for a pole at 0), sorted by
        decreasing real part like :meth:`poles`."""
        p = self.poles()
        wn = np.abs(p)
        with np.errstate(invalid="ignore", divide="ignore"):
            zeta = -p.real / wn
        return wn, zeta, p

    def open_loop(self, input, output) -> "LinearModel":
        """The model with the comparator ``e = input - output`` removed: ``input`` then drives
        ``e`` directly and ``(open_loop, output, input)`` is the loop transfer function.

        Valid only if ``input`` enters the circuit solely through ``input - output`` (a
        set point compared with a measurement) and ``output`` has no feedthrough from it.
        """
        j, i = self._loop_indices(input, output)
        cb = self.C[i:i + 1]
        return self._with(self.A + self.B[:, j:j + 1] @ cb, self.B,
                          self.C + self.D[:, j:j + 1] @ cb, self.D)

    def feedback(self, input, output, gain=1.0) -> "LinearModel":
        """Close ``input = gain * (r - output)``; ``r`` takes the place of ``input``.

        ``m.open_loop(u, y).feedback(u, y)`` is ``m`` again; ``gain`` is a proportional
        controller in series with the loop.
        """
        j, i = self._loop_indices(input, output)
        try:
            gain = float(gain)
        except (TypeError, ValueError):
            raise TypeError(f"feedback gain must be a number, got {gain!r}") from None
        if not np.isfinite(gain):
            raise ValueError(f"feedback gain must be finite, got {gain!r}")
        cb, bj, dj = self.C[i:i + 1], self.B[:, j:j + 1], self.D[:, j:j + 1]
        B, D = self.B.copy(), self.D.copy()
        B[:, j:j + 1] *= gain
        D[:, j:j + 1] *= gain
        return self._with(self.A - gain * bj @ cb, B, self.C - gain * dj @ cb, D)

    def root_locus(self, output=0, input=0, gains=None):
        """``(gains, loci)``: closed-loop poles of ``gain * (input -> output)`` under negative
        unity feedback, one row per gain (``control.root_locus_map``)."""
        control = _control()
        if gains is not None:
            try:
                gains = np.atleast_1d(np.asarray(gains, dtype=float))
            except (TypeError, ValueError):
                raise ValueError(f"root_locus: gains must be numbers, got {gains!r}") from None
            if gains.ndim != 1 or gains.size == 0 or not np.all(np.isfinite(gains)):
                raise ValueError(f"root_locus: gains must be a non-empty 1-D array of finite "
                                 f"numbers, got {gains!r}")
        data = control.root_locus_map(self.siso(output, input), gains=gains)
        return np.asarray(data.gains), np.asarray(data.loci)

    def _loop_indices(self, input, output):
        j = self._idx(input, self.input_names, "input")
        i = self._idx(output, self.output_names, "output")
        if self.D[i, j] != 0.0:
            raise PvgraphError(f"output {self.output_names[i]!r} has a direct feedthrough from "
                               f"input {self.input_names[j]!r}; the loop through them is "
                               f"algebraic and cannot be opened or closed here")
        return j, i

    def _with(self, A, B, C, D) -> "LinearModel":
        return LinearModel(A, B, C, D, list(self.state_names), list(self.input_names),
                           list(self.output_names), self.op)

    def step(self, t, output=0, input=0, amplitude=1.0) -> np.ndarray:
        """Response of ``output`` to a step of size ``amplitude`` in ``input`` at t = 0."""
        from scipy import signal
        i = self._idx(output, self.output_names, "output")
        j = self._idx(input, self.input_names, "input")
        t = _times(t, "t")
        sys = signal.StateSpace(self.A, self.B[:, j:j + 1], self.C[i:i + 1], self.D[i:i + 1, j:j + 1])
        _, yout, _ = signal.lsim(sys, np.full(len(t), amplitude), t)
        return np.asarray(yout).reshape(-1)


def _resonance_points(roots, zeta_max=0.2, per_resonance=801) -> np.ndarray:
    """Frequencies [rad/s] around each lightly damped root (damping ratio below
    ``zeta_max``): ``wn (1 +- 10 zeta)``, evenly, ``per_resonance`` points."""
    out = []
    for r in np.asarray(roots, dtype=complex):
        wn = abs(r)
        if wn == 0.0 or not np.isfinite(wn) or abs(r.imag) == 0.0:
            continue
        zeta = abs(r.real) / wn
        if zeta < zeta_max:
            half = max(10.0 * zeta, 1e-6) * wn
            out.append(np.linspace(max(wn - half, 1e-3 * wn), wn + half, per_resonance))
    return np.concatenate(out) if out else np.zeros(0)


def _same_value(a, b) -> bool:
    """Two parameter values (numbers or tables) are equal."""
    try:
        return bool(np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float)))
    except (TypeError, ValueError):
        return a == b


def _pole_text(q) -> str:
    """A pole near the imaginary axis as ``0``, ``+317.4j`` or, where its real part is not
    exactly zero, with it (``-2.1e-09+317.4j``)."""
    re_, im = float(q.real), float(q.imag)
    if re_ == 0.0 and im == 0.0:
        return "0"
    return (f"{re_:.2g}" if re_ != 0.0 else "") + (f"{im:+.4g}j" if im != 0.0 else "")


def _control():
    """python-control, or a PvgraphError naming the extra that installs it."""
    try:
        import control
    except ImportError:
        raise PvgraphError("this needs python-control, which is not installed: pip install "
                           "\"pvgraph[control]\" (or control)") from None
    return control


def _dc_gain_singular(A, B, C, D, state_names):
    """``(G(0), integrating state names)`` of a model whose ``A`` has eigenvalues at 0.

    An ordered Schur form ``A = Q T Q^T`` puts the eigenvalues at 0 (``|lambda|`` within
    rounding of ``||A||``) in the leading block ``T11``; a Sylvester equation decouples it
    from the regular block ``T22``. The regular part gives the finite limit
    ``D - C2 T22^-1 B2``; the nilpotent part adds ``sum_k C1 T11^(k-1) B1 / s^k``, infinite
    wherever one of those coefficients is not negligible.
    """
    import scipy.linalg as sla
    n = A.shape[0]
    # balanced first (a diagonal similarity by powers of two, exact): the states of a
    # hydraulic model span some fifteen decades (Pa against m^3), and the Schur vectors of
    # the unbalanced A mix its blocks at the percent level
    A, Tb = sla.matrix_balance(A, permute=False, separate=False)
    B, C = B / np.diag(Tb)[:, None], C * np.diag(Tb)[None, :]
    scale = max(np.linalg.norm(A, 1), np.finfo(float).tiny)
    lam = np.linalg.eigvals(A)
    tol = max(1e3 * np.finfo(float).eps * scale, np.min(np.abs(lam)) * (1.0 + 1e-6))
    T, Q, k = sla.schur(A, output="real", sort=lambda re, im: math.hypot(re, im) <= tol)
    k = max(int(k), 1)
    T11, T12, T22 = T[:k, :k], T[:k, k:], T[k:, k:]
    X = sla.solve_sylvester(T11, -T22, -T12) if k < n else np.zeros((k, 0))
    Bt, Ct = Q.T @ B, C @ Q
    B1, B2 = Bt[:k] - X @ Bt[k:], Bt[k:]          # the decoupled blocks
    C1, C2 = Ct[:, :k], Ct[:, :k] @ X + Ct[:, k:]
    G = D - C2 @ np.linalg.solve(T22, B2) if k < n else D.astype(float).copy()
    size = np.abs(C).sum(axis=1)[:, None] * np.abs(B).sum(axis=0)[None, :]
    lead = np.zeros_like(G)
    power = np.eye(k)
    for m in range(k):                   # keep the coefficient of the highest power of 1/s
        term = C1 @ power @ B1
        significant = np.abs(term) > 1e-9 * size * scale ** m
        lead = np.where(significant, term, lead)
        power = power @ T11
    G = np.where(lead != 0.0, np.copysign(np.inf, lead), G)
    weight = np.abs(Q[:, :k]).max(axis=1)
    names = [state_names[i] for i in np.flatnonzero(weight >= 0.5 * weight.max())]
    return G, names


def _times(t, what) -> np.ndarray:
    """``t`` as an increasing 1-D array of at least two finite times, or a ValueError."""
    try:
        t = np.asarray(t, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: times [s] as numbers, got {t!r}") from None
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError(f"{what}: at least two finite, increasing times [s], got shape "
                         f"{t.shape}")
    return t


def _step_grid(A, b, c) -> np.ndarray:
    """Times for the step response of ``(A, b, c)`` (see :meth:`LinearModel.step_info`)."""
    A, b, c = np.asarray(A, float), np.asarray(b, float), np.asarray(c, float)
    lam = np.linalg.eigvals(A) if A.size else np.zeros(0)
    weight = np.ones(len(lam))
    if A.size:
        lam, V = np.linalg.eig(A)
        if np.linalg.cond(V) < 1e10:        # modal shares of the step response
            share = (c @ V).ravel() * np.linalg.solve(V, b).ravel()
            with np.errstate(divide="ignore", invalid="ignore"):
                weight = np.abs(np.where(lam != 0, share / lam, share))
            top = weight.max() if weight.size else 0.0
            weight = weight / top if top > 0 else np.ones(len(lam))
    rate = -lam.real
    keep = (rate > 0.0) & (weight >= 1e-4)
    if not keep.any():
        keep = rate > 0.0
    if not keep.any():
        return np.linspace(0.0, 1.0, 20001)
    t_end = 10.0 / rate[keep].min()
    wanted = 50.0 * t_end * np.abs(lam[keep]).max()
    if wanted <= STEP_GRID_MAX:
        return np.linspace(0.0, t_end, int(max(wanted, 20000)) + 1)
    # a slow mode far below the fast ones (a leakage pole beside a hydraulic resonance): the
    # fast steps over the first half of the points, then even steps to t_end (one uniform grid
    # would step over the resonance's peak: 78 % overshoot read for 97.5 %)
    half = STEP_GRID_MAX // 2
    fine = np.linspace(0.0, half * t_end / wanted, half + 1)
    return np.concatenate([fine, np.linspace(fine[-1], t_end, half + 1)[1:]])


STEP_GRID_MAX = 500000      # points of a step response's time grid


def _step_response(control, sys, T) -> np.ndarray:
    """The unit step response of ``sys`` at the times ``T``, evenly spaced in segments."""
    steps = np.diff(T)
    cuts = np.flatnonzero(~np.isclose(steps[1:], steps[:-1], rtol=1e-9, atol=0.0)) + 1
    out, x0, start = [], None, 0
    for stop in list(cuts) + [len(steps)]:
        seg = T[start:stop + 1]
        res = control.forced_response(sys, seg - seg[0], np.ones(seg.size),
                                      X0=0.0 if x0 is None else x0, return_x=True)
        y = np.asarray(res.outputs).reshape(-1)
        out.append(y if not out else y[1:])
        x0 = np.asarray(res.states)[:, -1]
        start = stop
    return np.concatenate(out)


MARGIN_GRID_WIDENINGS = 6   # at most 12 more decades either way for a gain crossover


def _frequency_grid(roots, points_per_decade):
    """Log-spaced frequencies [rad/s] two decades around the magnitudes of ``roots``."""
    mag = np.abs(np.asarray(roots))
    mag = mag[np.isfinite(mag) & (mag > 0.0)]
    lo, hi = (np.log10(mag.min()) - 2.0, np.log10(mag.max()) + 2.0) if mag.size else (-2.0, 4.0)
    return np.logspace(lo, hi, max(int((hi - lo) * points_per_decade), 2))


def _jacobians(system, op):
    """``dF/dy`` and ``dF/dy'`` at the operating point, at its rates: a shaft angle that
    keeps turning has ``der(phi) = w`` there, and a machine's friction and flow laws read
    ``der(phi)`` (at zero rate they would be linearised at standstill)."""
    t, y = op.t, op.y
    yp = np.zeros(system.n) if getattr(op, "yp", None) is None else np.asarray(op.yp, float)
    J_y = system.jacobian_dense(t, y, yp, 0.0)
    J_yp = (system.jacobian_dense(t, y, yp, _C_BIG) - J_y) / _C_BIG
    if not (np.all(np.isfinite(J_y)) and np.all(np.isfinite(J_yp))):
        raise PvgraphError(f"{system.name}: the Jacobian is not finite at the operating point")
    return J_y, J_yp


def linearize(system: System, op: OperatingPoint, inputs: Mapping[str, np.ndarray] | None,
              outputs: Sequence[str], *, states: str = "differential",
              direct: Mapping[str, np.ndarray] | None = None,
              held: Mapping[str, Sequence[str]] | None = None,
              warn_stops: bool = True) -> LinearModel:
    """Linearise ``system`` at ``op``.

    Parameters
    ----------
    inputs : mapping name -> array (n,)
        Residual sensitivity ``dF/du`` of each input (see :func:`input_sensitivity`).
    outputs : names
        Any unknown or eliminated alias of the system (states, algebraic variables), a
        derived output (an orifice's ``q``, a power: its gradient at the operating point,
        through the rates of the states where it reads them), or an exposed-port name of one
        (:meth:`System.exposed_names`); the model keeps the names as given, and its methods
        also accept the other name of the same variable.
    direct : mapping name -> array (len(outputs),), optional
        ``d output / d u`` of each input at fixed unknowns: an output the compiler expressed
        in an input (a source's own flow ``pump.port.q = -Q``, a drive force holding ``k u``)
        moves with it directly; added to ``D``. For an input named as a runtime parameter
        of the system (``"orifice.A"``) the derived outputs' partial derivatives are taken
        from the compiled equations where ``direct`` does not give them.
    held : mapping name -> unknown names, optional
        The unknowns of :attr:`System.held_rates` each input moves (found by
        :func:`linearize_circuit`; for an input named as a runtime parameter they are read
        off ``system.held_rates``). Such an input sets an unknown whose rate the equations
        read (a position set directly, its velocity that position's rate), so it also acts
        through its own rate du/dt, which the model cannot hold: where that rate reaches
        the states or the outputs asked for, the input is refused with the unknowns it sets;
        where it reaches neither (a supply pressure whose rate only changes the flow into a
        volume at that pressure, not asked for) the model is exact and is returned. Not seen:
        a rate that reaches only an unknown the compiler removed. The flow a pressure source
        delivers into a volume at its own pressure, asked for as an output, misses its
        ``s V / beta`` term.
    warn_stops : bool
        Warn where the operating point rests on an end stop (a cylinder's ``F_stop``):
        a load that can only move has no other steady state (default True).
    """
    if states != "differential":
        raise PvgraphError(f"linearize: states={states!r}; the states are the differential "
                           f"variables ('differential')")
    if not isinstance(op, OperatingPoint):
        raise PvgraphError(f"linearize: op must be an OperatingPoint (steady_state's result), "
                           f"got {type(op).__name__}")
    if op.system is not system and list(op.system.names) != list(system.names):
        raise PvgraphError(f"linearize: the operating point is one of {op.system.name!r}, "
                           f"whose unknowns differ from those of {system.name!r}")
    from ..simulate import _name_list
    from .steady import _Scaled
    if op.system is not system:
        r = _Scaled(system, op.t, op.y).norm(op.y, op.yp)
        if not r <= max(1e-6, 100.0 * op.residual_norm):
            raise PvgraphError(f"linearize: the operating point is not a steady state of "
                               f"{system.name!r} (scaled residual {r:.3g} there): it was found "
                               f"for another system (other parameter values?); use "
                               f"steady_state(system)")
        # found with other runtime parameters (steady_state(system, params=...)): a volume, a
        # bulk modulus or a mass moves no steady state, only the dynamics linearised here
        theirs = op.system.parameters
        differ = [nm for nm, info in system.parameters.items() if nm in theirs and
                  not _same_value(theirs[nm].value, info.value)]
        if differ:
            told = "; ".join(f"{nm} = {theirs[nm].value!r} there, {system.parameters[nm].value!r}"
                             f" here" for nm in differ[:3])
            more = f" and {len(differ) - 3} more" if len(differ) > 3 else ""
            raise PvgraphError(f"linearize: the operating point was found with other parameter "
                               f"values than the system's ({told}{more}): linearise the system "
                               f"it was found for, linearize(op.system, op, ...)")
    outputs = _name_list(outputs, "linearize: outputs")
    for what, arg in (("inputs", inputs), ("direct", direct)):
        if arg is not None and not isinstance(arg, Mapping):
            raise PvgraphError(f"linearize: {what} must be a mapping {{input name: array}}, "
                               f"got {type(arg).__name__}")
    inputs = dict(inputs or {})
    direct = dict(direct or {})
    held = {name: set(got) for name, got in dict(held or {}).items()}
    for name in inputs:   # a parameter input: the unknowns it is known to fix
        held.setdefault(name, set()).update(
            v for v, (params, _) in system.held_rates.items() if name in params)
    for name, col in direct.items():
        if name not in inputs:
            raise PvgraphError(f"linearize: direct names {name!r}, which is not an input; the "
                               f"inputs are {list(inputs)}")
        try:
            col = np.asarray(col, dtype=float)
        except (TypeError, ValueError):
            col = np.zeros(0)
        if col.size != len(outputs) or not np.all(np.isfinite(col)):
            raise PvgraphError(f"linearize: direct[{name!r}]: d outputs/du must be "
                               f"{len(outputs)} finite numbers (one per output), got "
                               f"{direct[name]!r}")
    for name, col in inputs.items():
        try:
            col = np.asarray(col, dtype=float)
        except (TypeError, ValueError):
            col = np.zeros((0,))
        if col.size != system.n or not np.all(np.isfinite(col)):
            raise PvgraphError(f"linearize: input {name!r}: dF/du must be {system.n} finite "
                               f"numbers, got shape {col.shape}")
    n = system.n
    x = np.flatnonzero(system.differential)
    z = np.flatnonzero(system.algebraic)
    J_y, J_yp = _jacobians(system, op)
    yp_op = np.zeros(n) if getattr(op, "yp", None) is None else np.asarray(op.yp, float)
    F_u = np.column_stack([np.asarray(v, dtype=float).reshape(n) for v in inputs.values()]) \
        if inputs else np.zeros((n, 0))
    M = np.hstack([J_yp[:, x], J_y[:, z]])
    try:
        S = -np.linalg.solve(M, np.hstack([J_y[:, x], F_u]))
    except np.linalg.LinAlgError as exc:
        raise PvgraphError(f"{system.name}: [dF/dx', dF/dz] is singular at the operating "
                           f"point; the DAE is not index one there ({exc})") from None
    nx = len(x)
    A, B = S[:nx, :nx], S[:nx, nx:]
    Zx, Zu = S[nx:, :nx], S[nx:, nx:]
    pos_x = {int(k): r for r, k in enumerate(x)}
    pos_z = {int(k): r for r, k in enumerate(z)}
    C = np.zeros((len(outputs), nx))
    D = np.zeros((len(outputs), len(inputs)))
    # each output's dependence on [x', z] (for the check of the inputs' rates below)
    W = np.zeros((len(outputs), n))
    for r, name in enumerate(outputs):
        real = system.resolve_name(name)
        if real in system.observed and real not in system.index:
            # a derived output h(y, y'): its gradient, algebraic unknowns through Zx, Zu and
            # the states' rates through x' = A x + B u
            gy, gyp = system.observed_gradient(real, op.t, op.y, yp_op)
            if np.any(gyp[z] != 0.0):
                rate_of = system.names[int(z[np.flatnonzero(gyp[z])[0]])]
                raise PvgraphError(
                    f"linearize: {name!r} reads the rate of an algebraic variable "
                    f"({rate_of}), which a state-space model does not hold (it would need the "
                    f"inputs' rates)")
            C[r] = gy[x] + gy[z] @ Zx + gyp[x] @ A
            D[r] = gy[z] @ Zu + gyp[x] @ B
            W[r, :nx], W[r, nx:] = gyp[x], gy[z]
            # an input that is a parameter the output reads (an orifice's q against its
            # area): its partial derivative at fixed unknowns, unless given in ``direct``
            for j, u in enumerate(inputs):
                if u not in direct and u in system.parameters:
                    D[r, j] += system.output_gradient(real, op.t, op.y, yp_op, names=[u])[1][0]
            continue
        coef, idx, _ = system.resolve(name)
        if idx is None:
            continue
        if idx in pos_x:
            C[r, pos_x[idx]] = coef
        else:
            C[r] = coef * Zx[pos_z[idx]]
            D[r] = coef * Zu[pos_z[idx]]
            W[r, nx + pos_z[idx]] = coef
    _check_rates(system, held, M, W, nx, outputs)
    for j, name in enumerate(inputs):
        if name in direct:
            D[:, j] += np.asarray(direct[name], dtype=float).reshape(len(outputs))
    # the steady drift of a turning machine (its shafts' common angle) that no output reads is
    # a bare integrator: it is taken out of the model (a joined shaft keeps its twist)
    from .steady import reduce_drift
    A, B, C, x, state_names = reduce_drift(op, A, B, C, x)
    if warn_stops:
        _warn_on_stops(system, op, yp_op)
    return LinearModel(A, B, C, D, state_names, list(inputs), list(outputs), op)


def _warn_on_stops(system, op, yp):
    """Say where the operating point rests on an end stop (a cylinder's ``F_stop``): a
    circuit whose load can only move has no other steady state, and the model then is that
    of the rod pressed on its stop, not of the motion."""
    stops = [nm for nm in system.observed if nm.endswith(".F_stop")]
    if not stops:
        return
    try:
        got = system.evaluate_observed(np.array([op.t]), op.y[None, :], yp[None, :],
                                       [list(system.modes)])
    except Exception:   # noqa: BLE001  (an output that cannot be evaluated: nothing to say)
        return
    on = [(nm, float(got[nm][0])) for nm in stops if abs(float(got[nm][0])) > 1.0]
    if on:
        told = ", ".join(f"{nm} = {f / 1e3:.4g} kN" for nm, f in on[:3])
        warnings.warn(PlausibilityWarning(
            f"linearize: the operating point rests on an end stop ({told}): the model is "
            f"that of the rod pressed on its stop. Where the load only ever moves (a rod "
            f"driven at a steady speed), no other steady state exists; linearise along the "
            f"motion from a simulated instant instead (an OperatingPoint of sol.y, sol.yp at "
            f"that time)."), stacklevel=3)


def input_sensitivity(build: Callable[[dict], object], u0: Mapping[str, float], name: str,
                      op: OperatingPoint, *, eps_rel: float = 1e-5,
                      du: float | None = None) -> np.ndarray:
    """``dF/du`` of input ``name`` by central differences of rebuilt systems at ``op``."""
    return _input_derivatives(build, u0, name, op, (), eps_rel, du)[0]


def _input_derivatives(build, u0, name, op, outputs, eps_rel=1e-5, du=None):
    """``(dF/du, d outputs/du at fixed unknowns, the unknowns of System.held_rates it moves)``
    of input ``name`` by central differences
    of rebuilt systems at ``op``; at a bound of the input (a damping of 0, which the component
    refuses below) by one-sided second-order differences into the allowed side."""
    u0 = dict(u0)
    h = du if du is not None else eps_rel * (abs(u0[name]) if u0[name] != 0.0 else 1.0)

    def at(step):
        u = dict(u0)
        u[name] = u0[name] + step
        s = _as_system(build(u))
        if s.names != op.system.names:
            raise PvgraphError(f"changing input {name!r} changed the unknowns of the compiled "
                               f"system; linearise a build whose structure does not depend on it")
        values = []
        derived = None
        # the unknowns fixed to parameters whose rates the equations read, at this value
        held = {v: s.resolve(v)[2] for v in s.held_rates}
        for out in outputs:
            real = s.resolve_name(out)
            if real in s.observed and real not in s.index:
                if derived is None:
                    yp = np.zeros(s.n) if op.yp is None else np.asarray(op.yp, float)
                    derived = s.evaluate_observed(np.array([op.t]), op.y[None, :], yp[None, :],
                                                  [list(s.modes)])
                values.append(float(derived[real][0]))
                continue
            coef, idx, off = s.resolve(out)
            values.append(off + (0.0 if idx is None else coef * op.y[idx]))
        return s.residual(op.t, op.y, op.yp), np.array(values, dtype=float), held

    moved = set()

    def rate_check(a, b):
        moved.update(v for v in a[2] if a[2][v] != b[2].get(v))

    refused = {}
    for sign in (1.0, -1.0):
        try:
            refused[sign] = at(sign * h)
        except ParameterError as exc:
            refused[sign] = exc
    up, down = refused[1.0], refused[-1.0]
    if not isinstance(up, Exception) and not isinstance(down, Exception):
        rate_check(up, down)
        return (up[0] - down[0]) / (2.0 * h), (up[1] - down[1]) / (2.0 * h), moved
    if isinstance(up, Exception) and isinstance(down, Exception):
        raise PvgraphError(f"input {name!r} = {u0[name]!r}: neither {name} + {h:g} nor "
                           f"{name} - {h:g} is a valid value ({up}); give du={{{name!r}: "
                           f"...}} a step the component accepts") from None
    # one-sided: f'(u) = (-3 f(u) + 4 f(u + s) - f(u + 2 s)) / (2 s), s = +h or -h
    sign = 1.0 if not isinstance(up, Exception) else -1.0
    one = up if sign > 0 else down
    two = at(2.0 * sign * h)
    zero = at(0.0)
    rate_check(two, zero)
    step = sign * h
    return ((-3.0 * zero[0] + 4.0 * one[0] - two[0]) / (2.0 * step),
            (-3.0 * zero[1] + 4.0 * one[1] - two[1]) / (2.0 * step), moved)


def _check_rates(system, held, M, W, nx, outputs):
    """Refuse an input that acts through its own rate on the states or on the outputs.

    The rows reading the rate of an unknown an input fixes (``held``) are where du/dt would
    enter; ``-M^-1`` maps a change of those rows to ``[x', z]``. Where that reaches a state's
    rate or an output (``W``: each output's dependence on ``[x', z]``), the model would drop
    a term (nonzero up to rounding: 1e-9 of the entries' scale).
    """
    row_of = {label: k for k, label in enumerate(system.equations)}
    for name, moved in held.items():
        rows = sorted({row_of[label] for v in moved
                       for label in system.held_rates.get(v, ((), ()))[1] if label in row_of})
        if not rows:
            continue
        E_ = np.zeros((M.shape[0], len(rows)))
        E_[rows, range(len(rows))] = 1.0
        G = np.linalg.solve(M, E_)
        scale = np.abs(G).max(axis=0)
        reaches = []
        if np.any(np.abs(G[:nx]) > 1e-9 * scale):
            reaches.append("the states' rates")
        out = np.abs(W @ G) > 1e-9 * (np.abs(W) @ np.abs(G))
        hit = [outputs[r] for r in np.flatnonzero(out.any(axis=1))]
        if hit:
            reaches.append("the output" + ("s " if len(hit) > 1 else " ") +
                           ", ".join(repr(h) for h in hit))
        if reaches:
            raise PvgraphError(_rate_text(name, sorted(moved), " and ".join(reaches)))


def _rate_text(name: str, moved, reaches: str) -> str:
    """The refusal of an input that acts through its own rate."""
    names = ", ".join(moved[:4]) + (f" and {len(moved) - 4} more" if len(moved) > 4 else "")
    return (f"linearize: input {name!r} sets {names} directly (fixed to its value), and the "
            f"equations read the rate of {'it' if len(moved) == 1 else 'them'} (a position "
            f"set by the input, its velocity the position's rate): the input acts on "
            f"{reaches} through its own rate du/dt, which a linear model x' = A x + B u, "
            f"y = C x + D u does not hold. Take as the input what drives that motion through "
            f"the circuit's dynamics (a force on the mass, a flow into the volume), or set "
            f"the position through a stiff spring or a position controller.")


def _si_number(value, what: str) -> float:
    """An input value as an SI float: a number, or a quantity with a unit ("6 L/min")
    converted to SI; the inputs are differenced, so anything else is refused by name."""
    from ..units import to_si
    if not isinstance(value, bool):
        try:
            value = to_si(value, what)
        except PvgraphError:
            pass
        if isinstance(value, (int, float, np.integer, np.floating)):
            if not math.isfinite(float(value)):
                raise PvgraphError(f"{what} = {value!r} is not finite")
            return float(value)
    raise PvgraphError(f"{what} = {value!r}: give a number (SI) or a quantity with a unit "
                       f"('6 L/min')")


def _as_system(target):
    return target if isinstance(target, System) else target.compile()


def linearize_circuit(build: Callable[[dict], object], u0: Mapping[str, float],
                      outputs: Sequence[str], *, y0=None, eps_rel: float = 1e-5,
                      du: Mapping[str, float] | None = None, tol: float = 1e-9,
                      op: OperatingPoint | None = None) -> LinearModel:
    """Compile ``build(u0)``, find its steady state (from ``y0``) and linearise it.

    ``build`` maps a dict of input values to a Circuit (or System); the inputs of the model are
    the keys of ``u0``, in order.
    """
    if not isinstance(u0, Mapping) or not u0:
        raise PvgraphError(f"u0: a non-empty mapping {{input name: value}}, got {u0!r}")
    from ..simulate import _name_list
    outputs = _name_list(outputs, "linearize_circuit: outputs")
    if not outputs:
        raise PvgraphError("outputs: name at least one variable")
    if not (isinstance(eps_rel, (int, float)) and eps_rel > 0.0 and math.isfinite(eps_rel)):
        raise PvgraphError(f"eps_rel must be a positive number, got {eps_rel!r}")
    given = dict(u0)
    u0 = {name: _si_number(value, f"u0[{name!r}]") for name, value in u0.items()}
    quantities = {name: v for name, v in given.items() if not isinstance(v, (int, float, bool))
                  and not isinstance(v, (np.integer, np.floating))}
    if quantities:
        # the components check a quantity's dimension against their field's: a circuit built
        # from the values as given refuses '2 mm' for an area (the SI number would not)
        try:
            build(given)
        except PvgraphError:
            raise
        except Exception:   # noqa: BLE001  (build computes with the values: numbers only)
            pass
    for name, step in dict(du or {}).items():
        if name not in u0:
            raise PvgraphError(f"du names {name!r}, which is not an input; the inputs are "
                               f"{list(u0)}")
        if not (isinstance(step, (int, float)) and step > 0.0 and math.isfinite(step)):
            raise PvgraphError(f"du[{name!r}] must be a positive number, got {step!r}")
    built = build(dict(u0))
    if built is None:
        raise PvgraphError("build(u0) returned None; it must return a Circuit or a System")
    system = _as_system(built)
    for name, value in quantities.items():   # an input that is a parameter: its unit
        info = system.parameters.get(name)
        if info is not None and getattr(info, "unit", None) is not None:
            from ..units import number_in
            number_in(value, info.unit, f"u0[{name!r}]")
    for name in outputs:
        system.resolve_name(name)   # an unknown name is told (with close matches) up front
    if op is None:
        op = steady_state(system, y0=y0, tol=tol)
    du = dict(du or {})
    cols, direct, held = {}, {}, {}
    for nm in u0:
        cols[nm], direct[nm], held[nm] = _input_derivatives(build, u0, nm, op, list(outputs),
                                                            eps_rel, du.get(nm))
    unused = [nm for nm in u0 if not np.any(cols[nm]) and not np.any(direct[nm])
              and not held[nm]]
    if unused:
        # an input the build reads (a parameter of the compiled system moves with it) but
        # whose effect vanishes at this operating point (a spring's rate at zero deflection)
        # is not a mistake of the build's: say which it is
        base = system.parameter_values
        read, ignored = [], []
        for nm in unused:
            u = dict(u0)
            u[nm] = u0[nm] + (du.get(nm) or eps_rel * (abs(u0[nm]) or 1.0))
            moved = _as_system(build(u)).parameter_values
            (read if moved != base else ignored).append(nm)
        if read:
            warnings.warn(f"linearize_circuit: input(s) {read} have no first-order effect at "
                          f"this operating point (dF/du = 0 there, though the circuit's "
                          f"parameters move with them): the model's column for them is zero",
                          UserWarning, stacklevel=2)
        if ignored:
            warnings.warn(f"linearize_circuit: input(s) {ignored} change nothing in the "
                          f"circuit (dF/du = 0 and no parameter moves): does build(u) read "
                          f"u[{ignored[0]!r}]? The model's column for it is zero", UserWarning,
                          stacklevel=2)
    return linearize(system, op, cols, outputs, direct=direct, held=held)
