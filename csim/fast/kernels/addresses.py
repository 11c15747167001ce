"""The compiled-only part of the kernels: a mechanism's model functions, an external gamma*,
``feval`` and the elimination's solve called through their addresses, and the core's model
handle over them.

The model functions are C (``cc``, :mod:`csim.fast.ccodegen`) or numba cfuncs
(:mod:`csim.fast.codegen`) with one interface (:mod:`csim.fast.layout`); their addresses are
entries of ``pi``. The core (:mod:`csim.physics.model`) reaches the model through a handle,
here the tuple ``(par, pi, w, ym, t)``, for which the core's ``model_*`` functions are
overloaded (ym: a state [q, qd, W] to call the model functions at, t: their time). The interpreted package
has the same names in :mod:`.interpreted`; :mod:`.calls` imports one or the other.
"""
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.callconv import excinfo_t
from numba.core.errors import TypingError
from numba.extending import intrinsic, overload

from csim.fast.layout import F_JAC, F_MASS, F_PHI, F_TERMS, PI_FN, PI_ND, W_GAM, W_J, W_M, W_PHI, W_PT
from csim.physics.model import model_gamma, model_jacobian, model_mass, model_phi, model_phi_t

from .common import inlined


# ---------------------------------------------------------------------------------------
# calls through a function's address (a C function, or a numba cfunc)
# ---------------------------------------------------------------------------------------
def _lower_call(context, builder, argtys, args):
    """Call the C function at the address args[0] with args[1:]: arrays as pointers to their
    data (no reference counting), integers and floats by value. Returns nothing."""
    llargs, lltys = [], []
    for ty, value in zip(argtys[1:], args[1:]):
        if isinstance(ty, types.Array):
            llargs.append(context.make_array(ty)(context, builder, value).data)
            lltys.append(context.get_data_type(ty.dtype).as_pointer())
        else:
            llargs.append(value)
            lltys.append(context.get_value_type(ty))
    fnty = ir.FunctionType(ir.VoidType(), lltys)
    builder.call(builder.inttoptr(args[0], fnty.as_pointer()), llargs)
    return context.get_dummy_value()


@intrinsic
def call_model(typingctx, addr, t, y, par, out):
    """``void f(double t, const double *y, const double *par, double *out)`` at address ``addr``."""
    if not (isinstance(addr, types.Integer) and isinstance(t, types.Float)):
        return None
    sig = types.void(addr, t, y, par, out)

    def codegen(context, builder, signature, args):
        return _lower_call(context, builder, signature.args, args)
    return sig, codegen


@intrinsic
def call_gamma(typingctx, addr, r, gamma, phi, phi_dot, gains, n_gains, fpar, n_fpar, ipar, n_ipar, out):
    """``void g(int64 r, const double *gamma, const double *phi, const double *phi_dot, const double *gains,
    int64 n_gains, const double *fpar, int64 n_fpar, const int64 *ipar, int64 n_ipar, double *out)``."""
    sig = types.void(addr, r, gamma, phi, phi_dot, gains, n_gains, fpar, n_fpar, ipar, n_ipar, out)

    def codegen(context, builder, signature, args):
        return _lower_call(context, builder, signature.args, args)
    return sig, codegen


#: the argument types ``feval`` is compiled for (:func:`csim.fast.module.addressed_function`), and its callers
#: call it with: (t, y, mode, located, par, pf, pi, w, piv, f, info)
_F8, _I8 = types.Array(types.float64, 1, "C"), types.Array(types.int64, 1, "C")
FEVAL_TYPES = (types.float64, _F8, types.Array(types.boolean, 1, "C"), types.boolean, _F8, _F8, _I8, _F8, _I8, _F8,
               _F8)
#: ... and the elimination's solve, ``eliminated``: (pf, pi, w, piv)
ELIMINATED_TYPES = (_F8, _I8, _F8, _I8)


def _typed_call(name, signature, addr, argtys):
    """The typing of a call ``call(addr, *args)`` of the function ``name``, compiled for the argument types
    ``signature`` (returning int64), at the address ``addr``, with numba's own calling convention:
    (signature, codegen) for an intrinsic.

    numba links the LLVM IR of every function a compiled function calls into it, and
    optimizes and emits the whole again: each of the dozen functions that evaluate the
    right-hand side (the steppers' stages, the dense outputs, the first step, Radau's
    Jacobian) carried its own copy of the right-hand side's closure, a third of the cold
    compile. Called by address, such a function is compiled once, on its own, for
    ``signature`` (the arguments must be exactly those: the call is typed only for them). As
    numba's own call does, an error status (an exception, which nothing there raises today but
    ``NUMBA_BOUNDSCHECK=1`` would) is passed on to the caller instead of read as a result.
    (``_get_arg_packer`` and ``_get_return_status`` are numba's, 0.60 to 0.68.)
    """
    if not isinstance(addr, types.Integer):
        return None
    for i, (got, want) in enumerate(zip(argtys, signature)):
        if got != want:
            raise TypingError(f"call of {name}: argument {i + 1} is {got}; {name} is compiled for {want} "
                              f"(csim.fast.kernels.addresses)")
    sig = types.int64(addr, *argtys)

    def codegen(context, builder, sig_, args):
        call_conv = context.call_conv
        fnty = call_conv.get_function_type(types.int64, argtys)
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        result = cgutils.alloca_once(builder, call_conv.get_return_type(types.int64).pointee)
        builder.store(cgutils.get_null_value(result.type.pointee), result)
        excinfo = cgutils.alloca_once(builder, ir.PointerType(excinfo_t))
        packed = list(call_conv._get_arg_packer(argtys).as_arguments(builder, args[1:]))
        code = builder.call(fn, [result, excinfo, *packed])
        status = call_conv._get_return_status(builder, code, builder.load(excinfo))
        with cgutils.if_unlikely(builder, status.is_error):
            call_conv.return_status_propagate(builder, status)
        return context.get_returned_value(builder, types.int64, builder.load(result))
    return sig, codegen


@intrinsic
def call_feval(typingctx, addr, t, y, mode, located, par, pf, pi, w, piv, f, info):
    """``feval(t, y, ...)`` (:data:`FEVAL_TYPES`) called through its address pi[PI_FEVAL] (:func:`_typed_call`)."""
    return _typed_call("feval", FEVAL_TYPES, addr, (t, y, mode, located, par, pf, pi, w, piv, f, info))


@intrinsic
def call_eliminated(typingctx, addr, pf, pi, w, piv):
    """``eliminated(pf, pi, w, piv)`` (:data:`ELIMINATED_TYPES`) called through its address pi[PI_ELIM]
    (:func:`_typed_call`)."""
    return _typed_call("eliminated", ELIMINATED_TYPES, addr, (pf, pi, w, piv))


# ---------------------------------------------------------------------------------------
# the core's model handle (csim.physics.model) in the kernels: the tuple (par, pi, w, ym, t),
# ym a state [q, qd, W] to call the model functions at, t the time [s] (drive rows depend on it)
# ---------------------------------------------------------------------------------------
#: the compile options of the overloads (as the kernels', less the cache: they compile into their callers)
CALL_OPTIONS = dict(error_model="numpy", _nrt=False)


# (A process that imports both the compiled copy and the package's own source registers these overloads
# once, from the copy: the source's addresses.py is never imported, the interpreted package's calls are
# interpreted.py's.)
def _is_handle(model):
    return isinstance(model, types.BaseTuple)


def _overload_at_q(core_fn, fn, slot):
    """Overload ``core_fn(model, q, out)`` for the kernels' handle: the model function ``fn`` (its index in
    MODEL_FUNCTIONS) at q, then out = its term, read from w at the offset pi[slot]."""

    @overload(core_fn, jit_options=CALL_OPTIONS, strict=False, inline="always")
    def _typer(model, q, out):
        if not _is_handle(model):
            return None

        def impl(model, q, out):
            par, pi, w, ym, t = model
            for i in range(q.size):
                ym[i] = q[i]
            call_model(pi[PI_FN + fn], t, ym, par, w)
            for i in range(out.size):
                out[i] = w[pi[slot] + i]
        return impl
    return _typer


_overload_at_q(model_phi, F_PHI, W_PHI)
_overload_at_q(model_jacobian, F_JAC, W_J)
_overload_at_q(model_mass, F_MASS, W_M)


@overload(model_phi_t, jit_options=CALL_OPTIONS, strict=False, inline="always")
def _model_phi_t(model, q, out):
    if _is_handle(model):
        def impl(model, q, out):
            par, pi, w, ym, t = model
            if pi[PI_ND] == 0:  # no drive rows: the mechanism's own rows do not depend on t
                for i in range(out.size):
                    out[i] = 0.0
                return
            for i in range(q.size):
                ym[i] = q[i]
            call_model(pi[PI_FN + F_PHI], t, ym, par, w)  # phi_ writes Phi and Phi_t
            for i in range(out.size):
                out[i] = w[pi[W_PT] + i]
        return impl
    return None


@overload(model_gamma, jit_options=CALL_OPTIONS, strict=False, inline="always")
def _model_gamma(model, q, qd, out):
    if _is_handle(model):
        def impl(model, q, qd, out):
            par, pi, w, ym, t = model
            m = q.size
            for i in range(m):
                ym[i] = q[i]
                ym[m + i] = qd[i]
            call_model(pi[PI_FN + F_TERMS], t, ym, par, w)
            for i in range(out.size):
                out[i] = w[pi[W_GAM] + i]
        return impl
    return None


@inlined
def model_handle(par, pi, w, ym, t):
    """The core's model handle at time t [s]: the tuple (par, pi, w, ym, t) the overloads above take."""
    return (par, pi, w, ym, t)
