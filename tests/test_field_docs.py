"""Every field of every public type says what it is, and every float field its unit (issue 20, deliverable 5).

The public types are the dataclasses and NamedTuples of the modules the API reference documents
(the ``::: module`` lines of docs/reference/*.md; a module's ``__all__`` when it has one, else the
non-underscore classes it defines). A field is documented when its name appears as an entry of the
class docstring (``name:`` / ``name,`` at the start of an entry, or the first mention) or when an
attribute docstring follows it in the class body; a float field's entry must carry a unit in brackets
(``[m]``, ``[N]``, ``[-]`` for dimensionless). :data:`NOT_YET` may list classes that do not pass yet (it
is empty); a listed class that passes fails the test, so the list can only shrink.
"""
from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import re
import textwrap
import typing
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "docs" / "reference"

# Classes not yet complete, "module.Class" each (empty: every public type passes). A listed class that passes
# fails the test, so the list can only shrink.
NOT_YET: set[str] = set()


def reference_modules() -> list[str]:
    names = []
    for page in sorted(REFERENCE.glob("*.md")):
        names += re.findall(r"^:::\s+([\w.]+)", page.read_text(), flags=re.M)
    return names


def public_types() -> list[type]:
    seen: dict[str, type] = {}
    for name in reference_modules():
        module = importlib.import_module(name)
        members = getattr(module, "__all__", None)
        if members is None:
            members = [k for k, v in vars(module).items() if inspect.isclass(v) and v.__module__ == name]
        for key in members:
            obj = getattr(module, key, None)
            if inspect.isclass(obj) and not key.startswith("_") and (dataclasses.is_dataclass(obj) or is_namedtuple(obj)):
                seen[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return [seen[k] for k in sorted(seen)]


def is_namedtuple(cls: type) -> bool:
    return issubclass(cls, tuple) and hasattr(cls, "_fields")


def field_types(cls: type) -> dict[str, str]:
    """Field name -> its annotation as text (public fields only)."""
    if dataclasses.is_dataclass(cls):
        fields = [(f.name, f.type) for f in dataclasses.fields(cls)]
    else:
        fields = list(typing.get_type_hints(cls).items()) if cls.__annotations__ else [(f, "") for f in cls._fields]
    return {k: (t if isinstance(t, str) else getattr(t, "__name__", str(t))) for k, t in fields if not k.startswith("_")}


def attribute_docs(cls: type) -> dict[str, str]:
    """Docstrings written under a field in the class body (``x: float = 0.0`` then ``\"\"\"... [m]\"\"\"``)."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError):
        return {}
    body = tree.body[0].body
    out = {}
    for stmt, nxt in zip(body, body[1:]):
        if isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name) and isinstance(nxt, ast.Expr) \
                and isinstance(getattr(nxt, "value", None), ast.Constant) and isinstance(nxt.value.value, str):
            out[stmt.target.id] = nxt.value.value
    return out


def entry(doc: str, name: str, names: list[str]) -> str | None:
    """The part of ``doc`` that describes field ``name``: from its entry (or first mention) to the next entry."""
    start_pat = r"(?:^|\n|;|\.)\s*(?:``)?{}(?:``)?\s*[:,(]"
    m = re.search(start_pat.format(re.escape(name)), doc) or re.search(rf"(?<![\w.]){re.escape(name)}(?![\w])", doc)
    if m is None:
        return None
    pos = m.end()
    ends = [len(doc)]
    for other in names:
        if other != name:
            n = re.compile(start_pat.format(re.escape(other))).search(doc, pos)
            if n:
                ends.append(n.start() + 1)
    return doc[m.start():min(ends)]


def problems(cls: type) -> list[str]:
    doc = inspect.getdoc(cls) or ""
    if doc.startswith(f"{cls.__name__}("):  # the generated signature, not a docstring
        doc = ""
    attrs = attribute_docs(cls)
    types = field_types(cls)
    out = []
    for name, kind in types.items():
        text = attrs.get(name) or entry(doc, name, list(types))
        if text is None:
            out.append(f"{name}: undocumented")
        elif "float" in kind and not re.search(r"\[[^\]]+\]", text):
            out.append(f"{name}: no unit in brackets ([m], [N], [-] ...)")
    return out


TYPES = public_types()


def test_the_reference_documents_public_types():
    assert len(TYPES) >= 10 and not (NOT_YET - {f"{c.__module__}.{c.__qualname__}" for c in TYPES})


@pytest.mark.parametrize("cls", TYPES, ids=lambda c: f"{c.__module__}.{c.__qualname__}")
def test_every_field_has_a_docstring_with_units(cls):
    name = f"{cls.__module__}.{cls.__qualname__}"
    found = problems(cls)
    if name in NOT_YET:
        assert found, f"{name} passes now: remove it from NOT_YET"
        return
    assert not found, f"{name}: " + "; ".join(found)
