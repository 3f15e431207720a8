"""Every mutation of mk/mutations.toml still applies to the code it names.

A refactor that moves or rewrites a mutated line leaves its mutation unable to apply: `make
mutate` (too slow for `make test`) then reports an error, and until someone runs it the claim
the mutation stood for is unchecked. This happened twice (the half/difference cosine and the
prefetched read moved when the lookup was split). Here, in the fast suite: each mutation's
text occurs exactly once in its file (mutate.py's own rule), and the mutation changes it.
"""
import importlib.util
import sys
from pathlib import Path

import pytest

TOP = Path(__file__).resolve().parent.parent


def _mutate_module():
    spec = importlib.util.spec_from_file_location("mutate_under_test", TOP / "mk" / "mutate.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


MUTATE = _mutate_module()
MUTATIONS = MUTATE.load()


def test_the_list_is_not_trivial():
    assert len(MUTATIONS) >= 40


@pytest.mark.parametrize("m", MUTATIONS, ids=[m.id for m in MUTATIONS])
def test_mutation_applies_exactly_once(m):
    text = (TOP / m.file).read_text()
    assert text.count(m.find) == 1, f"{m.file}: {m.find!r} occurs {text.count(m.find)} times"
    assert m.replace != m.find

