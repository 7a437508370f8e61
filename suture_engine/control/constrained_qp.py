"""The per-tick velocity QP of move-constrained, on one persistent OSQP problem.

Decision variables ``z = (qdot, s)``: the joint velocities qdot (4) [rad/s, rad/s,
rad/s, m/s] and one slack per soft row. Each tick:

    minimise  1/2 |J qdot - v_ref|_W^2 + 1/2 lambda |qdot|^2 + 1/2 w_s |s|^2
    subject to
      lo <= qdot <= hi        joint velocity limits, joint position limits over one tick
                              horizon, and the singularity margin on q2 and q4 (3.22-3.23)
      Jc J qdot + s  = -k_c C(x)       each equality fixture row (6.1-6.4, 6.31, 6.45)
      Jc J qdot + s <= -k_c g(x)       each inequality fixture row (cone)
      u_l^T J_p qdot + s <= ldot_max   the suture extension rate (4.10-4.11)

with ``v_ref = v_target + K_x (x_target - x)`` (resolved rate with position feedback)
and ``u_l`` the unit vector from the suture's exit point to the tool tip, so that
``u_l^T J_p qdot`` is the rate of change of that distance.

The problem is set up once (fixed sparsity; every entry that can ever be non-zero is a
structural non-zero) and each tick only the values of q, l, u, P and A are passed to
``update``; OSQP warm-starts from the previous solution. A solve is capped by
``max_iter``; rho adapts every ``adaptive_rho_interval`` iterations (a fixed count, not
OSQP's setup-time-based default), so the same inputs give the same numbers on any
machine. ``time_limit`` (50 ms) is only a guard against a runaway solve; a hit is
counted in ``time_limit_hits``. When a solve does not end ``solved``, the previous
command is held and the failure counted (``failures``, ``consecutive_failures``).

Every soft row carries its own slack with a quadratic penalty ``w_s`` (default 1e5):
when the rows are feasible they hold up to (multiplier / w_s), about 1e-5 in the row's
rate units; when they are not (a tension bound already exceeded, a fixture the joint
limits cannot reach), the slack gives way and ``slack_max`` says by how much. The joint
box has no slack; the command is clipped into it after the solve.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.control.fixtures import Fixture
from suture_engine.errors import SutureError

if TYPE_CHECKING:
    from suture_engine.robot.params import EndoBotParams

__all__ = [
    "INF",
    "ConstrainedQP",
    "JointLimits",
    "QPError",
    "QPResult",
    "QPWeights",
    "extension_rate_bound",
]

Array = NDArray[np.float64]

INF = 1e30
"""OSQP's "no bound" (never pass it inf)."""

_N = 4


class QPError(SutureError):
    """The QP was configured with values it cannot use.

    Attributes:
        field: the offending field name.
        value: the offending value.
    """

    code = "bad-qp"

    def __init__(self, field: str, value: object, reason: str) -> None:
        super().__init__(f"{field}={value!r}: {reason}")
        self.field = field
        self.value = value


def extension_rate_bound(f_max: float, static_friction: float, viscous_coefficient: float) -> float:
    """The largest suture extension rate that keeps the tension under f_max (4.10-4.11).

    ``ldot_max = (f_max - F_s) / F_v``.

    Args:
        f_max: tension limit [N].
        static_friction: suture-tissue static friction F_s [N].
        viscous_coefficient: viscous coefficient F_v [N*s/m], > 0.

    Returns:
        ldot_max [m/s]; not positive when f_max <= F_s (the suture may not be pulled).
    """
    if not viscous_coefficient > 0.0:
        raise QPError("viscous_coefficient", viscous_coefficient, "must be > 0 [N*s/m]")
    return (f_max - static_friction) / viscous_coefficient


@dataclass(frozen=True, eq=False)
class JointLimits:
    """Joint limits of one EndoBot and the singularity margin (3.22-3.23).

    The defaults are the E1 parameter set's joint limits (:func:`JointLimits.from_params`).

    Attributes:
        q_min: lower joint positions [rad, rad, rad, m].
        q_max: upper joint positions [rad, rad, rad, m].
        qd_max: joint speed limits [rad/s, rad/s, rad/s, m/s].
        horizon: look-ahead for the position limits [s] (one control tick).
        q2_margin: keep |q2| <= pi/2 - q2_margin [rad] (det J = c2 q4^2, (3.22)).
        q4_min: keep q4 >= q4_min [m] (the RCM singularity q4 = 0, (3.23)).
        singular_time_constant: approach time constant to the singularity margin [s]:
            the speed towards it is at most (distance to the margin) / this.
    """

    q_min: Array = field(default_factory=lambda: _robot_limits()[0])
    q_max: Array = field(default_factory=lambda: _robot_limits()[1])
    qd_max: Array = field(default_factory=lambda: _robot_limits()[2])
    horizon: float = 1e-3
    q2_margin: float = 0.2
    q4_min: float = 0.03
    singular_time_constant: float = 0.05

    def __post_init__(self) -> None:
        for name in ("q_min", "q_max", "qd_max"):
            arr = np.asarray(getattr(self, name), dtype=float).reshape(-1)
            if arr.shape != (_N,) or not np.all(np.isfinite(arr)):
                raise QPError(name, getattr(self, name), "expected 4 finite values")
            object.__setattr__(self, name, arr)
        if np.any(self.q_min >= self.q_max):
            raise QPError("q_min", self.q_min, "must be below q_max")
        if np.any(self.qd_max <= 0):
            raise QPError("qd_max", self.qd_max, "must be positive")
        if not self.horizon > 0 or not self.singular_time_constant > 0:
            raise QPError("horizon", self.horizon, "horizon and time constant must be > 0 [s]")

    @classmethod
    def from_params(cls, params: EndoBotParams | None = None, **overrides: Any) -> JointLimits:
        """The joint limits of a robot parameter set (None: E1), with optional overrides.

        Args:
            params: the robot's parameters.
            overrides: other fields (``horizon``, ``q2_margin``...).
        """
        lo, hi, qd = _robot_limits(params)
        return cls(q_min=lo, q_max=hi, qd_max=qd, **overrides)


def _robot_limits(params: EndoBotParams | None = None) -> tuple[Array, Array, Array]:
    """(q_min, q_max, qd_max) of a parameter set's joints (None: E1)."""
    from suture_engine.robot.params import E1

    joints = (params or E1).joints
    return (
        np.array([j.limits.lower for j in joints]),
        np.array([j.limits.upper for j in joints]),
        np.array([j.limits.velocity for j in joints]),
    )


@dataclass(frozen=True, eq=False)
class QPWeights:
    """Weights and gains of the QP.

    Attributes:
        task: diagonal tracking weight W on (x, y, z, phi).
        damping: lambda, joint-velocity regularisation [-].
        slack: w_s, penalty on each slack (large: the rows are hard when feasible).
        position_gain: K_x on the task position error [1/s].
        fixture_gain: k_c, constraint error feedback [1/s] (C-dot = -k_c C).
    """

    task: Array = field(default_factory=lambda: np.array([1.0, 1.0, 1.0, 1e-2]))
    damping: float = 1e-4
    slack: float = 1e5
    position_gain: float = 10.0
    fixture_gain: float = 20.0

    def __post_init__(self) -> None:
        w = np.asarray(self.task, dtype=float).reshape(-1)
        if w.shape != (_N,) or np.any(w < 0) or not np.all(np.isfinite(w)):
            raise QPError("task", self.task, "expected 4 finite non-negative weights")
        object.__setattr__(self, "task", w)
        if not (self.damping > 0 and self.slack > 0):
            raise QPError("damping", (self.damping, self.slack), "damping, slack must be > 0")


class QPResult(NamedTuple):
    """One tick's solve.

    Attributes:
        qdot: the joint velocity command [rad/s, rad/s, rad/s, m/s] (held on failure).
        status: OSQP's status text (``"solved"``, ``"maximum iterations reached"``...).
        solved: whether this tick's solution was used.
        iterations: ADMM iterations.
        solve_time_s: OSQP's own solve time [s].
        active: names of the rows at a bound (equality fixture rows always included).
        slack_max: the largest slack magnitude [row units]; > 0 means a hard row gave way.
    """

    qdot: Array
    status: str
    solved: bool
    iterations: int
    solve_time_s: float
    active: tuple[str, ...]
    slack_max: float


def _osqp() -> Any:
    import osqp  # lazy: validate must not import it

    return osqp


class ConstrainedQP:
    """Move-constrained's persistent velocity QP (see the module docstring).

    Args:
        fixtures: the virtual fixtures held in this state.
        limits: joint limits and singularity margin.
        weights: weights and gains.
        extension_rate: add the suture extension-rate row (4.10-4.11).
        settings: OSQP settings overriding the defaults (``max_iter``, ``time_limit`` [s],
            ``eps_abs``...).

    Attributes:
        solves: solves so far.
        failures: solves that did not end ``solved`` (the previous command was held).
        consecutive_failures: failures since the last successful solve.
        time_limit_hits: failures on the wall-clock guard ``time_limit``.
    """

    def __init__(
        self,
        fixtures: Sequence[Fixture] = (),
        *,
        limits: JointLimits | None = None,
        weights: QPWeights | None = None,
        extension_rate: bool = False,
        settings: dict[str, Any] | None = None,
    ) -> None:
        import scipy.sparse as sp  # lazy

        self.fixtures = tuple(fixtures)
        self.limits = limits or JointLimits()
        self.weights = weights or QPWeights()
        self.extension_rate = extension_rate
        self.failures = 0
        self.consecutive_failures = 0
        self.solves = 0
        self.time_limit_hits = 0
        m_fix = sum(f.rows for f in self.fixtures)
        m_soft = m_fix + (1 if extension_rate else 0)
        self.n = _N + m_soft
        self.m = _N + m_soft
        self._m_soft = m_soft
        names = [f"joint_bound[{j}]" for j in range(_N)]
        eq_rows = []
        for fx in self.fixtures:
            for r in range(fx.rows):
                if fx.kind == "eq":
                    eq_rows.append(len(names))
                names.append(f"{fx.name}[{r}]")
        if extension_rate:
            names.append("extension_rate")
        self.row_names: tuple[str, ...] = tuple(names)
        self._eq_set = frozenset(eq_rows)

        # Preallocated buffers, and views into them, filled in place every tick by the
        # compiled kernels of :mod:`suture_engine.control._qp_kernels`.
        w = self.weights
        self._H = np.zeros((_N, _N))
        # G: the soft rows of A over qdot, stored flat with a trailing 1.0 so that one
        # gather fills every value of A (the identity entries point at that 1.0).
        self._gflat = np.zeros(m_soft * _N + 1)
        self._gflat[-1] = 1.0
        self._G = self._gflat[:-1].reshape(m_soft, _N)
        self._q = np.zeros(self.n)
        self._l = np.full(self.m, -INF)
        self._u = np.full(self.m, INF)
        self._qdot = np.zeros(_N)
        self._active_rows = np.zeros(self.m, dtype=np.int8)
        self._active_names: dict[bytes, tuple[str, ...]] = {}
        # per soft row: 1 for an equality fixture row (always active)
        self._eq = np.array([1 if i in self._eq_set else 0 for i in range(_N, self.m)], np.int8)
        m_fix = self._m_soft - (1 if extension_rate else 0)
        self._c_buf = np.zeros(m_fix)
        self._jc_buf = np.zeros((m_fix, _N))
        self._p0 = np.zeros((m_fix, 3))
        # Lines and planes: C(x) = Jc[:, :3] (p - p0) with a constant Jc, evaluated by the
        # kernel (no per-tick linearize); any other fixture is linearised in Python.
        affine = [fx.affine() for fx in self.fixtures]
        self._affine = bool(affine) and all(a is not None for a in affine)
        if self._affine:
            r = 0
            for fx, a in zip(self.fixtures, affine, strict=True):
                assert a is not None
                self._jc_buf[r : r + fx.rows] = a[0]
                self._p0[r : r + fx.rows] = a[1]
                r += fx.rows
        self._ext_row = m_fix if extension_rate else -1
        self._empty3 = np.zeros(3)
        self._empty4 = np.zeros(_N)

        # P: dense upper triangle over qdot, diagonal over the slacks.
        rows_p, cols_p = [], []
        for j in range(_N):
            for i in range(j + 1):
                rows_p.append(i)
                cols_p.append(j)
        n_qd = len(rows_p)  # the kernel writes these first values of Px, in this order
        rows_p += list(range(_N, self.n))
        cols_p += list(range(_N, self.n))
        self._Px = np.ones(len(rows_p))
        self._Px[n_qd:] = w.slack
        P = sp.csc_matrix((self._Px.copy(), (rows_p, cols_p)), shape=(self.n, self.n))
        # A: identity over qdot for the bounds; dense soft block; identity over the slacks.
        one = m_soft * _N
        rows_a, cols_a, gidx = [], [], []
        for j in range(_N):
            rows_a.append(j)
            cols_a.append(j)
            gidx.append(one)
            for r in range(m_soft):
                rows_a.append(_N + r)
                cols_a.append(j)
                gidx.append(r * _N + j)
        for r in range(m_soft):
            rows_a.append(_N + r)
            cols_a.append(_N + r)
            gidx.append(one)
        A = sp.csc_matrix((np.ones(len(rows_a)), (rows_a, cols_a)), shape=(self.m, self.n))
        # The entries were listed column by column, rows ascending: CSC order, so data
        # position k of A is entry k of the lists above. Check it once.
        if A.nnz != len(rows_a) or not np.array_equal(A.indices, rows_a):
            raise QPError("A", A.nnz, "unexpected sparsity layout")
        self._a_idx = np.array(gidx)
        self._Ax = np.ones(len(rows_a))

        defaults: dict[str, Any] = {
            "verbose": False,
            "warm_starting": True,
            "polishing": False,
            "eps_abs": 1e-5,
            "eps_rel": 1e-5,
            "max_iter": 4000,
            # A guard only: a normal tick ends on max_iter or convergence, never on the
            # clock, so the numbers do not depend on the machine's load. An overrun is
            # counted in ``time_limit_hits`` and the previous command is held.
            "time_limit": 0.05,
            "check_termination": 10,
            "adaptive_rho": True,
            # A fixed iteration interval: OSQP's default (0) derives it from the measured
            # setup time, which makes two runs of the same seed differ.
            "adaptive_rho_interval": 25,
        }
        defaults.update(settings or {})
        # A row counts as active within twice the solver's absolute tolerance.
        self._act_tol = 2.0 * float(defaults["eps_abs"]) + 1e-9
        self._solver = _osqp().OSQP()
        self._solver.setup(P, self._q, A, self._l, self._u, **defaults)
        # OSQP's compiled solver object: its update_data_vec/update_data_mat/solve are
        # what the Python wrapper's update()/solve() call, minus ~40 us of per-call
        # bookkeeping (bound clipping copies, derivative cache, an info namespace).
        # Our bounds are already within +-1e30, so nothing is lost by calling it directly.
        low = getattr(self._solver, "_solver", None)
        needed = ("update_data_vec", "update_data_mat", "solve", "info", "solution")
        self._low = low if low is not None and all(hasattr(low, a) for a in needed) else None
        from suture_engine.control import _qp_kernels as kern

        self._assemble_kernel, self._finish_kernel, self.compiled = kern.JIT
        lim = self.limits
        cst = np.zeros(kern.C_SIZE)
        cst[kern.C_TASK : kern.C_TASK + _N] = w.task
        cst[kern.C_DAMP] = w.damping
        cst[kern.C_POS_GAIN] = w.position_gain
        cst[kern.C_FIX_GAIN] = -w.fixture_gain
        cst[kern.C_HORIZON] = lim.horizon
        cst[kern.C_INV_TAU] = 1.0 / lim.singular_time_constant
        cst[kern.C_EDGE] = math.pi / 2 - lim.q2_margin
        cst[kern.C_Q4_MIN] = lim.q4_min
        cst[kern.C_QMIN : kern.C_QMIN + _N] = lim.q_min
        cst[kern.C_QMAX : kern.C_QMAX + _N] = lim.q_max
        cst[kern.C_QD : kern.C_QD + _N] = lim.qd_max
        self._cst = cst
        self._flag_x = kern.F_XTARGET
        self._flag_v = kern.F_VTARGET
        self._flag_e = kern.F_EXIT
        self._flag_a = kern.F_AFFINE

    # ------------------------------------------------------------------ assembly
    def solve(
        self,
        q: Array,
        x: Array,
        jacobian: Array,
        *,
        v_target: Array | None = None,
        x_target: Array | None = None,
        exit_point: Array | None = None,
        extension_rate_max: float | None = None,
    ) -> QPResult:
        """Update the persistent problem in place, solve it warm-started, return the command.

        Args:
            q: joint positions [rad, rad, rad, m].
            x: task vector (x, y, z, phi) = k(q) (3.13) [m, m, m, rad].
            jacobian: the analytical Jacobian dx/dq (3.21), shape (4, 4).
            v_target: feed-forward task velocity [m/s, m/s, m/s, rad/s] (default 0).
            x_target: task target for the position feedback (default: none).
            exit_point: the suture's exit point [m]; the extension-rate row is off without it.
            extension_rate_max: ldot_max [m/s] (4.11).

        Returns:
            The tick's QPResult.
        """
        self._assemble(q, x, jacobian, v_target, x_target, exit_point, extension_rate_max)
        low = self._low
        if low is not None:
            # positional: (q, l, u) and (P_x, P_i, A_x, A_i); pybind11's keyword matching
            # costs ~0.5 us a tick
            low.update_data_vec(self._q, self._l, self._u)
            low.update_data_mat(self._Px, None, self._Ax, None)
            low.solve()
            info = low.info
            return self._finish(info.status, info.iter, info.solve_time, low.solution.x)
        s = self._solver
        s.update(q=self._q, l=self._l, u=self._u, Px=self._Px, Ax=self._Ax)
        res = s.solve(raise_error=False)
        return self._finish(res.info.status, res.info.iter, res.info.solve_time, res.x)

    def _assemble(
        self,
        q: Array,
        x: Array,
        J: Array,
        v_target: Array | None,
        x_target: Array | None,
        exit_point: Array | None,
        extension_rate_max: float | None,
    ) -> None:
        # The fixture rows' C(x) and Jc(x) (Python objects), then one compiled call fills
        # P, q, l, u and A (see _qp_kernels.assemble).
        fixtures = self.fixtures
        flags = 0
        if self._affine:
            c, jc = self._c_buf, self._jc_buf
            flags = self._flag_a
        elif len(fixtures) == 1:
            c, jc = fixtures[0].linearize(x)
        else:
            c, jc = self._c_buf, self._jc_buf
            r = 0
            for fx in fixtures:
                cf, jf = fx.linearize(x)
                c[r : r + fx.rows] = cf
                jc[r : r + fx.rows] = jf
                r += fx.rows
        if x_target is None:
            x_target = self._empty4
        else:
            flags |= self._flag_x
        if v_target is None:
            v_target = self._empty4
        else:
            flags |= self._flag_v
        ldot = 0.0
        if exit_point is None or extension_rate_max is None:
            exit_point = self._empty3
        else:
            flags |= self._flag_e
            ldot = float(extension_rate_max)
        self._assemble_kernel(
            J,
            x,
            x_target,
            v_target,
            q,
            c,
            jc,
            self._p0,
            self._eq,
            exit_point,
            ldot,
            flags,
            self._ext_row,
            self._cst,
            self._H,
            self._gflat,
            self._Px,
            self._q,
            self._l,
            self._u,
            self._a_idx,
            self._Ax,
        )

    def _finish(self, status: str, iters: int, solve_time: float, z: Array | None) -> QPResult:
        self.solves += 1
        if status == "solved" and z is not None and z.shape == (self.n,):
            # The joint box is hard: clip the solver's tolerance-level excursions
            # (eps_abs + eps_rel * |z|) so the command never leaves it. A fresh array,
            # read-only: handed to the result as it is (hold() copies it).
            qdot = np.empty(_N)
            act = self._active_rows
            slack = self._finish_kernel(
                z, self._l, self._u, self._gflat, self._eq, self._act_tol, qdot, act
            )
            if slack >= 0.0:  # -1: a non-finite solution
                qdot.flags.writeable = False
                self._qdot = qdot
                self.consecutive_failures = 0
                key = act.tobytes()
                active = self._active_names.get(key)
                if active is None:
                    names = self.row_names
                    active = tuple(names[i] for i, a in enumerate(act.tolist()) if a)
                    self._active_names[key] = active
                return QPResult(
                    qdot, str(status), True, int(iters), float(solve_time), active, slack
                )
        self.failures += 1
        self.consecutive_failures += 1
        if status == "run time limit reached":
            self.time_limit_hits += 1
        return QPResult(
            qdot=self._qdot.copy(),
            status=str(status),
            solved=False,
            iterations=int(iters),
            solve_time_s=float(solve_time),
            active=(),
            slack_max=float("nan"),
        )

    # ------------------------------------------------------------------ introspection
    def matrices(self) -> tuple[Array, Array, Array, Array, Array]:
        """The current dense (P, q, A, l, u) (P full, symmetric), for independent checks."""
        P = np.zeros((self.n, self.n))
        P[:_N, :_N] = self._H
        P[_N:, _N:] = np.eye(self.n - _N) * self.weights.slack
        A = np.zeros((self.m, self.n))
        A[:_N, :_N] = np.eye(_N)
        A[_N:, :_N] = self._G
        A[_N:, _N:] = np.eye(self._m_soft)
        return P, self._q.copy(), A, self._l.copy(), self._u.copy()

    def update_settings(self, **settings: Any) -> None:
        """Change OSQP settings that may change after setup (``max_iter``, ``time_limit``...).

        Args:
            settings: OSQP setting names and values.
        """
        self._solver.update_settings(**settings)

    def hold(self) -> Array:
        """The last command that a successful solve produced [rad/s, ..., m/s]."""
        return self._qdot.copy()
