"""Fields that are pickled as one blob of bytes and unpickled where they are first read.

A linkage read back from the cache (:func:`csim.linkage.lambdacache.cached_build`) runs on
numeric functions that are cached as well; the sympy expressions they were derived from
(the transforms, the closure equations, the energies, the drawing) are read again only where
something derives anew: a plot's drawing, a cache miss. Rebuilding those expressions (sympy
canonicalises every product and sum it unpickles and asks about its assumptions) was most of
the time spent reading the linkage back: 0.45 s of the 81-link N-four-bar's warm run.
"""
from __future__ import annotations

import pickle


class DeferredFields:
    """Mixin: the fields named in the class attribute ``DEFERRED`` pickle as one blob of bytes,
    unpickled when any of them is first read.

    An instance that has not read them since it was unpickled passes the same bytes on when it
    is pickled again. A field set on the instance before the blob is read keeps its value.
    """

    #: the fields pickled as one blob (a plain class attribute: not a dataclass field)
    DEFERRED: tuple[str, ...] = ()

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        if "_deferred" not in state:  # read since unpickled, or never pickled: pickle the fields now
            fields = {name: state.pop(name) for name in type(self).DEFERRED if name in state}
            state["_deferred"] = pickle.dumps(fields, protocol=pickle.HIGHEST_PROTOCOL)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    def __getattribute__(self, name: str):
        if name in type(self).DEFERRED:
            own = object.__getattribute__(self, "__dict__")
            blob = own.get("_deferred")
            if blob is not None:
                for key, value in pickle.loads(blob).items():
                    own.setdefault(key, value)
                own.pop("_deferred", None)
        return object.__getattribute__(self, name)
