"""Which variant of the kernels this copy is: compiled or not, with or without the partitioned system.

The package's own source, imported as :mod:`csim.fast.kernels`, is never compiled: it is the
interpreted backend, the same loop run by Python (:mod:`.interpreted`). :mod:`csim.fast.module`
copies it twice into the cache with ``COMPILED = True``: as it is for ``minimal``, and with
``WITH_PARTITION = False`` for every other method.
"""


#: whether numba compiles this copy (True in the cache's copies, :func:`csim.fast.module.kernels_source`);
#: False in the source: every decorator of :mod:`.common` returns the function as it is, and the
#: model functions, ``feval`` and gamma* are called from Python (:mod:`.interpreted`)
COMPILED = False

#: whether this copy of the kernels carries the partitioned system (minimal coordinates, the
#: branches ``if WITH_PARTITION and ...``). :mod:`csim.fast.module` loads two copies: this
#: source for ``minimal``, and one written with False for every other method, in which numba
#: prunes those branches before typing them, so that it neither compiles the partitioned
#: path (two thirds of the compile time) nor pays for it at run time
WITH_PARTITION = True
