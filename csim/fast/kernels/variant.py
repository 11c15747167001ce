"""Whether this package is compiled: the cache's copy is, the package's own source is not.

The package's own source, imported as :mod:`csim.fast.kernels`, is never compiled: it is the
interpreted backend, the same loop run by Python (:mod:`.interpreted`). :mod:`csim.fast.module`
copies it, file for file unchanged, into the cache and imports the copy under a name of its
own (``csim_fast_kernels_<key>``): that copy numba compiles, for every method.
"""

#: whether numba compiles this package: True in the cache's copy, imported outside the package ``csim``
#: (:func:`csim.fast.module.load_kernels`); False in the source: every decorator of :mod:`.common` returns
#: the function as it is, and the model functions, ``feval`` and gamma* are called from Python
#: (:mod:`.interpreted`)
COMPILED = __name__.split(".", 1)[0] != "csim"
