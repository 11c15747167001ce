"""Whether this package is compiled: the cache's copy is, the package's own source is not.

The package's own source, imported as :mod:`csim.fast.kernels`, is never compiled: it is the
interpreted backend, the same loop run by Python (:mod:`.interpreted`). :mod:`csim.fast.module`
copies it, file for file unchanged, into the cache and imports the copy under a name of its
own (``csim_fast_kernels_<key>``): that copy numba compiles, for every method.
"""

#: whether numba compiles this package: True in the cache's copy, imported as ``csim_fast_kernels_<key>``
#: (:func:`csim.fast.module.load_kernels`); False in the source, imported as ``csim.fast.kernels`` (or
#: under any other name): every decorator of :mod:`.common` returns the function as it is, and the model
#: functions, ``feval`` and gamma* are called from Python (:mod:`.interpreted`)
COMPILED = __name__.startswith("csim_fast_kernels_")
