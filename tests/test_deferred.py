"""csim.model.deferred: fields pickled as one blob, unpickled where first read."""
from __future__ import annotations

import copy
import pickle
from dataclasses import dataclass, field

import pytest

from csim.model.deferred import DeferredFields

LOADS = []


class Counted:
    """A value whose unpickling is counted."""

    def __init__(self, value):
        self.value = value

    def __reduce__(self):
        return _counted, (self.value,)


def _counted(value):
    LOADS.append(value)
    return Counted(value)


@dataclass
class Record(DeferredFields):
    name: str
    heavy: Counted
    other: Counted | None = None
    cache: dict = field(default_factory=dict)

    DEFERRED = ("heavy", "other", "cache")


def test_deferred_fields_unpickle_where_first_read_and_all_at_once():
    LOADS.clear()
    r = pickle.loads(pickle.dumps(Record("a", Counted(1), Counted(2), {"k": 3})))
    assert LOADS == [] and r.name == "a"
    assert "heavy" not in vars(r) and "_deferred" in vars(r)
    assert r.other.value == 2  # a field with a class default: read from the blob, not the default
    assert sorted(LOADS) == [1, 2] and r.heavy.value == 1 and r.cache == {"k": 3}
    assert "_deferred" not in vars(r)


def test_an_unread_instance_passes_the_same_bytes_on():
    LOADS.clear()
    once = pickle.loads(pickle.dumps(Record("a", Counted(1))))
    twice = pickle.loads(pickle.dumps(once))
    assert LOADS == [] and twice.heavy.value == 1 and once.heavy.value == 1


def test_a_field_set_before_the_blob_is_read_keeps_its_value():
    r = pickle.loads(pickle.dumps(Record("a", Counted(1), Counted(2))))
    r.other = Counted(7)
    assert r.other.value == 7 and r.heavy.value == 1
    c = copy.deepcopy(pickle.loads(pickle.dumps(Record("b", Counted(4)))))
    assert c.heavy.value == 4 and c == c


def test_a_missing_attribute_is_still_an_attribute_error():
    r = pickle.loads(pickle.dumps(Record("a", Counted(1))))
    with pytest.raises(AttributeError, match="nothing"):
        r.nothing  # noqa: B018
    assert r.heavy.value == 1
