"""Run a case through the compiled kernels and return the usual :class:`Trajectory`.

Python packs the system (parameters, load laws, the method's settings) into arrays,
enters the compiled loop once, and turns its status code into the message the Python
driver (:func:`csim.solver.simulate.integrate`) gives for the same failure: both call
:func:`csim.solver.failures.failure_message`.
"""
from __future__ import annotations

import signal
import threading
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext, suppress

import numpy as np

from csim.fast.layout import CONSTRAINED, ELIMINATION, GGL, KKT, PARTITIONED, PI_HEAD, workspace
from csim.fast.module import (
    Drives,
    addressed_function,
    kernels_compiled,
    load_kernels,
    load_model,
    method_dispatch,
)
from csim.physics.events import chattering_switches
from csim.physics.jit import plain
from csim.physics.status import OK, STEP_TOO_SMALL, code_kind
from csim.solver.driven import DrivenSystem
from csim.solver.failures import failure_message, non_finite_note
from csim.solver.formulations import Elimination
from csim.solver.ggl_system import GGLSystem
from csim.solver.partitioned import PartitionedSystem
from csim.solver.settings import IntegrationSettings, Trajectory, output_times
from csim.solver.system import ConstrainedSystem

INTEGRATOR_CODES = {"DOP853": 0, "RK4": 1, "Radau": 3, "RK45": 4, "Tsit5": 5, "Vern7": 6}


def pack_problem(system: ConstrainedSystem, interpreted: bool = False,
                 feval: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(par, pf, pi)``: the problem as the flat arrays of :mod:`csim.fast.kernels` (``interpreted``: for the
    interpreted kernels, whose model functions and gamma* may be Python functions; ``feval`` False: feval's
    address left 0, for compiling an entry point from these arrays' types without compiling ``feval``: such
    arrays must never run).

    pf = [magnitudes (k), sw_value (n_sw), fpar (F), gains (G * r), the formulation's floats];
    pi = [mk, n_sw, at(ipar), I, at(fpar), F, at(gains), G * r, m, r, k, o, gamma* address, system kind, d,
    at(driven), feval's address, formulation, at(its integers), at(its
    floats), the elimination's address (0 for KKT), model function addresses, workspace offsets, sw_load
    (n_sw), sw_kind (n_sw), ipar (I), driven (d), the formulation's integers]
    (:mod:`csim.fast.layout`), where mk is the method's dispatch code and ``at(x)`` where x
    starts in pi or pf. The load laws are :class:`csim.load_laws.LoadSet`'s packing, the method's
    settings :meth:`csim.solver.methods.base.Method.pack`'s. A driven system's (:class:`DrivenSystem`)
    model has its d drives as its last constraint rows (r counts them), and its state the
    drives' work after the loads'. Builds the model functions on the first call for a
    mechanism (:func:`csim.fast.module.load_model`).
    """
    loads, method = system.loads, system.stabilizer
    drives = _drives(system)
    d = 0 if drives is None else len(drives.driven)
    model = load_model(system.model.definition, drives, interpreted)
    m, r, k, o = model.dims
    if (m, r, k) != (system.m, system.r + d, loads.magnitudes.size):
        raise RuntimeError(f"the compiled model of {model.name!r} has sizes {(m, r, k)}, the system "
                           f"{(system.m, system.r + d, loads.magnitudes.size)}")
    gains, fpar, ipar = method.pack(system.r + d)  # the drive rows are stabilized too
    n_sw = loads.n_switches
    at_ipar, at_fpar = PI_HEAD + 2 * n_sw, k + n_sw
    code, gamma_fn = method_dispatch(method, interpreted)
    kind = (PARTITIONED if isinstance(system, PartitionedSystem) else GGL if isinstance(system, GGLSystem)
            else CONSTRAINED)
    driven = np.zeros(0, np.int64) if drives is None else np.array(drives.driven, np.int64)
    form, form_i, form_f = _formulation(system.formulation, m - r)
    # the right-hand side and the elimination's solve, called by address (compiled or loaded here, on the first
    # run that needs them)
    kernels = load_kernels(compiled=not interpreted)
    feval_at = addressed_function(kernels, "feval") if feval else 0
    elim = addressed_function(kernels, "eliminated") if form == ELIMINATION else 0
    at_form_i, at_form_f = at_ipar + ipar.size + d, at_fpar + fpar.size + gains.size
    header = [code, n_sw, at_ipar, ipar.size, at_fpar, fpar.size, at_fpar + fpar.size, gains.size, m, r, k, o,
              gamma_fn, kind, d, at_ipar + ipar.size, feval_at, form, at_form_i, at_form_f, elim, *model.addresses,
              *workspace(m, r, k, n_sw)]
    pf = np.concatenate((loads.magnitudes, loads.sw_value, fpar, gains, form_f)).astype(float)
    pi = np.concatenate((header, loads.sw_load, loads.sw_kind, ipar, driven, form_i)).astype(np.int64)
    return np.ascontiguousarray(system.par, dtype=float), pf, pi


def _formulation(formulation, n: int) -> tuple[int, np.ndarray, np.ndarray]:
    """(code, integers, floats) of the formulation (:mod:`csim.fast.layout`): KKT, or ELIMINATION with
    [fixed (0/1), formulation.independent (n, ascending; zeros when not fixed)] and [max_condition]."""
    if not isinstance(formulation, Elimination):
        return KKT, np.zeros(0, np.int64), np.zeros(0)
    given = formulation.given if formulation.fixed else np.zeros(n, np.int64)
    return ELIMINATION, np.array([int(formulation.fixed), *given], np.int64), np.array([formulation.max_condition])


def _drives(system: ConstrainedSystem) -> Drives | None:
    """The drive rows of a driven system (:class:`csim.solver.driven.DrivenSystem`), else None."""
    if not isinstance(system, DrivenSystem):
        return None
    if system.expressions is None:
        raise RuntimeError("a driven system needs its drives' expressions to run compiled")
    return Drives(tuple(int(j) for j in system.driven), tuple(system.expressions))


def _arguments(system: ConstrainedSystem, y0: np.ndarray, settings: IntegrationSettings, max_steps: int,
               kernels, feval: bool = True) -> tuple:
    """The arguments of the kernel ``integrate`` (see its docstring) in ``kernels``, the compiled copy (whose
    ``feval`` is compiled, or loaded from numba's cache, here: the loop calls it by its address) or the
    interpreted package. ``feval`` False leaves the address 0, for compiling ``integrate`` from these
    arguments' types without compiling ``feval`` (:func:`compile_loop`): such arguments must never run."""
    t_out = output_times(settings.t_end, settings.output_dt)
    locate = settings.events and system.loads.n_switches > 0
    iset = np.array([int(locate), settings.event_samples, settings.max_events, max_steps, settings.chatter_events],
                    dtype=np.int64)
    fset = np.array([settings.t_end, settings.rtol, settings.atol, settings.step, settings.max_step,
                     np.nan if settings.first_step is None else settings.first_step, settings.max_phi,
                     settings.min_step], dtype=float)
    par, pf, pi = pack_problem(system, interpreted=not kernels.COMPILED, feval=feval)
    return (INTEGRATOR_CODES[settings.integrator], np.ascontiguousarray(y0, dtype=float), t_out,
            par, pf, pi, system.stabilizer.projects, iset, fset, np.zeros(2))


def _kernels_for(system: ConstrainedSystem, interpreted: bool = False):
    """The compiled kernels (:func:`csim.fast.module.load_kernels`), or the interpreted package."""
    return load_kernels(compiled=not interpreted)


def _chattering_labels(ev_sw: np.ndarray, n_ev: int, n_chatter: int, labels: list[str]) -> list[str]:
    """Labels of the switching functions that switched in the last ``n_chatter`` events (for CHATTER)."""
    involved = np.zeros(len(labels), bool)
    chattering_switches(ev_sw, int(n_ev), n_chatter, involved)
    return [labels[j] for j in np.flatnonzero(involved)]


def prepare(system: ConstrainedSystem, y0: np.ndarray, settings: IntegrationSettings) -> None:
    """Build the model functions (on the first run of a mechanism) and load the kernels' machine
    code (compiling it on the first run of an installation).

    numba loads or compiles a function on its first call; a call that stops after zero
    steps does that without integrating, so that a run's wall time is the run's alone.
    """
    from csim.progress import status

    load_model(system.model.definition, _drives(system))  # built first, with a status line of their own
    mod = _kernels_for(system)
    text = ("loading the compiled kernels" if kernels_compiled(mod) else
            "compiling the kernels (once per csim installation, about a minute; python -m csim.warmup "
            "compiles them ahead, on two cores in half the time)")
    with status(text), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        mod.integrate(*_arguments(system, y0, settings, 0, mod))  # (_arguments compiles feval)


def compile_loop(system: ConstrainedSystem, y0: np.ndarray, settings: IntegrationSettings) -> None:
    """Compile (or load) the kernels' loop, ``integrate``, and the projection's entry point (``project_entry``,
    of the tests), whose call tree is largely the loop's, for the types of their arguments, without calling
    them and without compiling the right-hand side (``feval``: :func:`compile_rhs`), which another process
    may compile at the same time (:mod:`csim.warmup`)."""
    from numba import typeof

    mod = _kernels_for(system)
    arguments = _arguments(system, y0, settings, 0, mod, feval=False)
    mod.integrate.compile(tuple(typeof(value) for value in arguments))
    y, par, pf, pi = arguments[1], arguments[3], arguments[4], arguments[5]
    mod.project_entry.compile(tuple(typeof(value) for value in (y, par, pf, pi)))


def compile_rhs(system: ConstrainedSystem, y0: np.ndarray) -> None:
    """Compile (or load) what the kernels hold besides :func:`compile_loop`'s, for the full state ``y0`` of a
    system that is not partitioned (their types are every method's): the right-hand side the loop calls by
    address (``feval``), the elimination's solve it calls by address (``eliminated``), the samples'
    evaluation (``evaluate_samples``) and the right-hand side's entry points (``rhs_entry`` of the tests,
    ``rhs_repeat`` of ``make bench``), each called once.

    What an entry point calls is compiled with it and never cached on its own
    (:mod:`csim.fast.linking`). The Python side's work (the mode at ``y0``: the core function
    ``switching_functions``) comes first: in the warm-up's job the kernels' callees get no machine
    code (:func:`csim.fast.linking.entry_points_only`), and Python can call none of them once an
    entry point has compiled it.
    """
    mod = _kernels_for(system)
    mode = system.mode_at(y0)
    n_sw = system.loads.n_switches
    addressed_function(mod, "feval")
    addressed_function(mod, "eliminated")
    evaluate_compiled(system, np.zeros(1), np.asarray(y0, dtype=float)[None], np.zeros((1, n_sw), dtype=bool))
    par, pf, pi = pack_problem(system)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        mod.rhs_entry(0.0, y0, mode, par, pf, pi)
        mod.rhs_repeat(y0, mode, par, pf, pi, 1)


def _plain_core(kernels):
    """For the interpreted package, :func:`csim.physics.jit.plain`: the core functions not compiled in this
    process run as Python (compiling each on its own would take minutes); nothing for a compiled copy."""
    return nullcontext() if kernels.COMPILED else plain()


#: how often the waiting thread reports progress and lets Python's signal handlers run [s]
WAIT_PERIOD = 0.05


def integrate_compiled(system: ConstrainedSystem, y0: np.ndarray, settings: IntegrationSettings,
                       progress: Callable[[float], None] | None = None, interpreted: bool = False) -> Trajectory:
    """:func:`csim.solver.simulate.integrate`, in compiled code (same arguments and result); with
    ``interpreted``, the same source run by Python (:mod:`csim.fast.kernels.interpreted`).

    The kernel runs without the GIL in a thread while this thread waits: Python's signal
    handlers run here, so Ctrl-C (KeyboardInterrupt) asks the kernel to stop through its
    ``control`` array, and it returns within a few hundred steps with the samples so far (a
    run failed with the kind ``interrupted``, as on the Python path); ``progress(t)`` gets the
    time reached every :data:`WAIT_PERIOD` seconds. The caller has checked the combination
    with :func:`csim.fast.support.unsupported`.
    """
    mod = _kernels_for(system, interpreted)
    args = _arguments(system, y0, settings, settings.max_steps, mod)
    try:
        n_rec, ts, ys, modes, n_ev, ev_t, ev_sw, nfev, nsteps, code, info, njev, nlu = _run_kernel(mod, args, progress)
    except _PythonArithmetic as exc:
        return _raised(system, exc.__cause__)
    labels = system.loads.switch_labels
    status, message, failure = "success", f"reached t_end = {settings.t_end:g} s", ""
    if code != OK:
        detail = failure_detail(system, int(code), info)
        status, failure = "failed", code_kind(int(code), detail)
        message = failure_message(int(code), float(info[0]), float(info[1]), settings, system.failure_method(int(code)),
                                  switches=_chattering_labels(ev_sw, n_ev, settings.chatter_events, labels),
                                  detail=detail, coordinates=system.model.definition.coordinate_names)
        if code == STEP_TOO_SMALL and np.isfinite(info[-1]):  # Radau rejected non-finite trial states
            message += non_finite_note(float(info[-1]))
    return Trajectory(
        t=ts[:n_rec].copy(), y=ys[:n_rec].copy(), mode=modes[:n_rec].copy(),
        status=status, message=message, failure=failure, nfev=int(nfev), njev=int(njev), nlu=int(nlu),
        nsteps=int(nsteps),
        event_times=ev_t[:n_ev].tolist(), event_labels=_event_labels(ev_sw[:n_ev], labels),
    )


def failure_detail(system: ConstrainedSystem, code: int, info: np.ndarray) -> np.ndarray | None:
    """The details of a failed kernel run's status ``code``, info[2:], where they are that code's: a step too small
    is worded from Radau's DAE details on GGL's system only (a partitioned system's info[2:] holds the partition's,
    which may be left from a breakdown the run got past)."""
    if code == STEP_TOO_SMALL and not isinstance(system, GGLSystem):
        return None
    return info[2:-1]


class _PythonArithmetic(Exception):
    """The interpreted loop raised where machine code goes on with inf or NaN (its ``__cause__``)."""


def _python_arithmetic(exc: BaseException) -> bool:
    """Whether ``exc`` is what Python raises where machine code computes inf or NaN: a float divided by zero,
    an overflow, a math function out of its domain, NaN made an integer. Anything else (a bug, a deliberate
    check of the loop, a plug-in's own error) is raised as it is."""
    if isinstance(exc, (ZeroDivisionError, OverflowError, FloatingPointError)):
        return True
    return isinstance(exc, ValueError) and str(exc) in ("math domain error", "cannot convert float NaN to integer")


def _raised(system: ConstrainedSystem, exc: BaseException) -> Trajectory:
    """The failed run of an interpreted kernel that raised where machine code goes on with inf or NaN (on the
    way to a blow-up), saying where."""
    from csim.fast.support import numba_usable

    frame = traceback.extract_tb(exc.__traceback__)[-1]
    inside = frame.filename.partition("/csim/")[2]  # the file from the package's folder on
    where = f"{'csim/' + inside if inside else frame.filename}:{frame.lineno} ({frame.name})"
    hint = "; run it compiled to see where the motion fails" if numba_usable() else ""
    message = (f"simulation.backend 'interpreted': Python raised {type(exc).__name__} ({exc}) at {where}, where "
               f"compiled code goes on with inf or NaN, on the way to a blow-up{hint}")
    return Trajectory(t=np.zeros(0), y=np.zeros((0, system.n_state)), mode=np.zeros((0, system.loads.n_switches), bool),
                      status="failed", message=message, failure="backend")


def _run_kernel(mod, args: tuple, progress: Callable[[float], None] | None) -> tuple:
    """``mod.integrate(*args)`` in a thread, this one waiting (see :func:`integrate_compiled`)."""
    control = args[-1]
    out: dict = {}

    def target() -> None:
        try:
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"), _plain_core(mod):
                out["value"] = mod.integrate(*args)
        except BaseException as exc:  # handed to the waiting thread
            out["error"] = exc
            if not mod.COMPILED and _python_arithmetic(exc):  # (not the progress callback's: raised below)
                out["error"] = _PythonArithmetic()
                out["error"].__cause__ = exc

    worker = threading.Thread(target=target, name="csim-kernel", daemon=True)
    with _stop_on_ctrl_c(control):
        worker.start()
        try:
            while worker.is_alive():
                worker.join(WAIT_PERIOD)
                if progress is not None:
                    progress(float(control[1]))
        finally:  # the progress callback raised: stop the kernel too, not leave it computing
            if worker.is_alive():
                control[0] = 1.0
                worker.join()
    if "error" in out:
        raise out["error"]
    return out["value"]


@contextmanager
def _stop_on_ctrl_c(control: np.ndarray) -> Iterator[None]:
    """While the block runs, Ctrl-C (SIGINT; in a worker process, the parent's
    :data:`csim.parallel.STOP_SIGNAL`) sets control[0], which stops the kernel with its
    samples so far, instead of raising KeyboardInterrupt here (which would lose them).

    The handler that was there is still called, so that whoever watches for Ctrl-C (the CLI,
    :class:`csim.parallel.InterruptFlag`) records it; the KeyboardInterrupt it raises is
    dropped: the run comes back as failed with the kind ``interrupted``, as on the Python
    path. Outside the main thread, or with SIGINT ignored, nothing changes.
    """
    from csim.parallel import STOP_SIGNAL

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    watched = {signum: signal.getsignal(signum) for signum in (signal.SIGINT, STOP_SIGNAL) if signum is not None}
    watched = {signum: previous for signum, previous in watched.items() if callable(previous)}

    def handler(signum, frame):
        control[0] = 1.0
        with suppress(KeyboardInterrupt):  # recorded by the handler; the run returns its samples
            watched[signum](signum, frame)
    for signum in watched:
        signal.signal(signum, handler)
    try:
        yield
    finally:
        for signum, previous in watched.items():
            signal.signal(signum, previous)


def _event_labels(switched: np.ndarray, labels: list[str]) -> list[str]:
    """Each event's label: the labels of the switches that changed, joined by "; " (one join per distinct row)."""
    if not len(switched):
        return []
    rows, index = np.unique(switched, axis=0, return_inverse=True)
    text = ["; ".join(labels[j] for j in np.flatnonzero(row)) for row in rows]
    return [text[i] for i in index.ravel()]


def evaluate_compiled(system: ConstrainedSystem, t: np.ndarray, y: np.ndarray,
                      mode: np.ndarray, interpreted: bool = False) -> dict[str, np.ndarray]:
    """The recorded quantities at the samples of a compiled run, in one compiled call (``interpreted``: of an
    interpreted run, by the interpreted package).

    Parameters
    ----------
    t : ndarray (N,)
        The sample times [s].
    y : ndarray (N, 2 m + k)
        The trajectory's states.
    mode : ndarray (N, n_sw) bool
        The load laws held at each sample.

    Returns
    -------
    dict
        ``ok`` (N,) bool (False: the formulation's solve failed, the row is NaN), ``qdd`` (N, m),
        ``lam`` (N, r), ``phi`` (N, r), ``phi_dot`` (N, r), ``loads`` (N, k),
        ``generalized_forces`` (N, m), ``kinetic`` (N,) and ``potential`` (N,) [J], as
        :meth:`csim.solver.system.ConstrainedSystem.evaluate` gives them one at a time,
        ``observables`` (N, o) and ``observable_rates`` (N, o), and ``drive_forces`` (N, d), a
        driven system's tau = -lambda_d (:meth:`csim.solver.driven.DrivenSystem.drive_forces`; d = 0 else).
    """
    par, pf, pi = pack_problem(system, interpreted)
    mod = _kernels_for(system, interpreted)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"), _plain_core(mod):
        ok, x, phi, phi_dot, u, Q, energy, obs = mod.evaluate_samples(
            np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(y, dtype=float),
            np.ascontiguousarray(mode, dtype=np.bool_), par, pf, pi)
    m, r, o = system.m, system.r, obs.shape[1] // 2  # (a driven system's drive rows follow its r rows)
    return dict(ok=ok, qdd=x[:, :m], lam=x[:, m:m + r], phi=phi[:, :r], phi_dot=phi_dot[:, :r], loads=u,
                drive_forces=-x[:, m + r:], generalized_forces=Q,
                kinetic=energy[:, 0], potential=energy[:, 1], observables=obs[:, :o], observable_rates=obs[:, o:])
