"""Which variant of the kernels this copy is: with or without the partitioned system.

:mod:`csim.fast.module` copies the kernels twice into the cache, this file as it is for
``minimal`` and with ``WITH_PARTITION = False`` for every other method.
"""


#: whether this copy of the kernels carries the partitioned system (minimal coordinates, the
#: branches ``if WITH_PARTITION and ...``). :mod:`csim.fast.module` loads two copies: this
#: source for ``minimal``, and one written with False for every other method, in which numba
#: prunes those branches before typing them, so that it neither compiles the partitioned
#: path (two thirds of the compile time) nor pays for it at run time
WITH_PARTITION = True
