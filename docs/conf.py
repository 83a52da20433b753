"""Sphinx configuration of the tsa-bench documentation site (built from docs/).

Build it with ``python3 -m sphinx -W -n -b html docs site`` (``pip install -e ".[docs]"``);
``tests/docs/test_site.py`` runs the same strict build in CI. Markdown pages are read by
MyST, the tutorial notebook by MyST-NB (executed during the build), the API reference
comes from the package's docstrings (autodoc) and the CLI reference from the click
commands (sphinx-click).
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# document the package next to these pages, not another installed copy
sys.path.insert(0, str(ROOT / "host"))

from tsa_bench import __version__  # noqa: E402

project = "tsa-bench"
author = "tsa-bench contributors"
copyright = "tsa-bench contributors"
version = release = __version__

extensions = [
    "myst_nb",               # Markdown (MyST) pages and the executed tutorial notebook
    "sphinx.ext.autodoc",    # API reference from docstrings
    "sphinx_click",          # CLI reference from the click commands
]
source_suffix = {".md": "myst-nb", ".ipynb": "myst-nb"}
root_doc = "index"
exclude_patterns = ["_build", "**.ipynb_checkpoints"]
html_theme = "furo"
html_title = f"tsa-bench {__version__}"

# Markdown: GitHub-style anchors for links such as `run-format.md#segments`
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence", "deflist"]

# Broken references are errors (the build runs with -W -n): only names of other packages,
# whose inventories are not fetched (the build is offline), are left unresolved.
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(np|numpy|h5py|serial|click|yaml|matplotlib|pyarrow|dask|scipy|pandas)(\..*)?"),
    (r"py:.*", r"(collections\.abc|typing|pathlib|dataclasses|enum|threading|io|os)\..*"),
    (r"py:.*", r"(Path|Any|Mapping|Sequence|Iterable|Iterator|Callable|NDArray|ArrayLike)"),
]

autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_preserve_defaults = False

# The tutorial runs during the build; a failing cell fails the build, a warning it prints too.
nb_execution_mode = "auto"
nb_execution_timeout = 300
nb_execution_raise_on_error = True
nb_output_stderr = "warn"
nb_merge_streams = True

# README sections are pages of the site (index, protocols, rig): their links into docs/ are
# made relative to docs/; a link to a file elsewhere in the repository becomes its path as
# code, since the site holds docs/ only.
_LINK = re.compile(r"\[([^\]]+)\]\(((?!https?:|mailto:|#)[^)\s]+)\)")


def _repo_links(text: str) -> str:
    def one(m: re.Match[str]) -> str:
        label, target = m.group(1), m.group(2)
        if target.startswith("docs/"):
            return f"[{label}]({target[len('docs/'):]})"
        shown = label.strip("`")
        return f"`{target}`" if shown == target else f"{label} (`{target}`)"

    return _LINK.sub(one, text)


def _include_read(app, relative_path: Path, parent_docname: str, content: list[str]) -> None:
    if Path(relative_path).name == "README.md":
        content[0] = _repo_links(content[0])


_MISSING = object()


def _scopes(module: str, cls: str) -> list[str]:
    """Where a name in a docstring of ``module`` (class ``cls``) may live: the module and its
    parents, the module that really defines the documented class (it may be documented under
    the package that re-exports it), and every module of the same room."""
    parts = module.split(".") if module else []
    scopes = [".".join(parts[:i]) for i in range(len(parts), 0, -1)]
    if module and cls:
        scopes.insert(0, f"{module}.{cls}")
        owner = _find(f"{module}.{cls}")
        if owner is not _MISSING and getattr(owner, "__module__", None):
            scopes[1:1] = [f"{owner.__module__}.{owner.__qualname__}", owner.__module__]
    if len(parts) >= 2:
        room = importlib.import_module(".".join(parts[:2]))
        scopes += [f"{room.__name__}.{m.name}" for m in pkgutil.iter_modules(getattr(room, "__path__", []))]
    return [""] + scopes


def _find(dotted: str):
    """The module or object ``dotted`` names (importing what it must), or ``_MISSING``."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:]:
            if hasattr(obj, name):
                obj = getattr(obj, name)
            elif name == parts[-1] and _instance_attribute(obj, name):
                return name
            else:
                return _MISSING
        return obj
    return _MISSING


def _instance_attribute(cls, name: str) -> bool:
    """Whether ``cls`` sets ``self.<name>`` in its code (an attribute of its instances)."""
    if not isinstance(cls, type):
        return False
    try:
        source = inspect.getsource(cls)
    except (OSError, TypeError):
        return False
    return re.search(rf"\bself\.{re.escape(name)}\b\s*(:[^=]+)?=", source) is not None


def _internal_reference(app, env, node, contnode):
    """A docstring may name a part of the package the reference leaves out (a private helper,
    an internal class): it stays as code, without a link. A name that exists nowhere is still
    reported (-n -W: the build fails)."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip(".~")
    for scope in _scopes(node.get("py:module") or "", node.get("py:class") or ""):
        dotted = f"{scope}.{target}" if scope else target
        if dotted.startswith("tsa_bench") and _find(dotted) is not _MISSING:
            return contnode
    return None


def _dataclass_defaults(app, what, name, obj, options, signature, return_annotation):
    """A dataclass field's ``default_factory`` shows as ``<factory>``, which is not Python:
    Sphinx cannot parse the signature then and splits it at every comma. Shown as ``...``."""
    if signature and "<factory>" in signature:
        return signature.replace("<factory>", "..."), return_annotation
    return None


def setup(app):
    app.connect("autodoc-process-signature", _dataclass_defaults)
    app.connect("include-read", _include_read)
    app.connect("missing-reference", _internal_reference)
