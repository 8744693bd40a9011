"""viewer_bridge.util.lru: a map bounded by the sizes of its values."""

from __future__ import annotations

from viewer_bridge.util.lru import SizedLru


def test_the_least_recently_used_go_first_and_are_handed_back() -> None:
    cache: SizedLru[str, str] = SizedLru(max_size=10)
    assert cache.put("a", "A", 4) == [] and cache.put("b", "B", 4) == []
    assert cache.get("a") == "A"  # now b is the least recently used
    assert cache.put("c", "C", 4) == ["B"]
    assert cache.keys() == ["a", "c"] and cache.total == 8 and len(cache) == 2
    assert cache.get("b") is None and "b" not in cache


def test_putting_a_held_key_keeps_the_first_value_and_size() -> None:
    cache: SizedLru[str, str] = SizedLru(max_size=10)
    cache.put("a", "first", 3)
    assert cache.put("a", "second", 9) == []
    assert cache.get("a") == "first" and cache.total == 3


def test_an_entry_larger_than_the_bound_is_kept_only_with_keep_newest() -> None:
    plain: SizedLru[str, str] = SizedLru(max_size=5)
    plain.put("small", "s", 2)
    assert plain.put("big", "B", 8) == ["s", "B"] and len(plain) == 0 and plain.total == 0
    newest: SizedLru[str, str] = SizedLru(max_size=5, keep_newest=True)
    newest.put("small", "s", 2)
    assert newest.put("big", "B", 8) == ["s"] and newest.keys() == ["big"] and newest.values() == ["B"]
