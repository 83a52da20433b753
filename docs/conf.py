"""Sphinx configuration of the tsa-bench documentation site (built from docs/).

Build it with ``python -m sphinx -W -n docs site`` (``pip install -e ".[docs]"``);
``tests/docs/test_site.py`` runs the same strict build in CI. Markdown pages are read by
MyST, the tutorial notebook by MyST-NB (executed during the build), the API reference
comes from the package's docstrings (autodoc) and the CLI reference from the click
commands (sphinx-click).
"""

from __future__ import annotations

import importlib
import inspect
import os
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
    (r"py:.*", r"(np|numpy|h5py|serial|click|yaml|matplotlib|pyarrow|dask|scipy|pandas|bluesky|ophyd_async|event_model)(\..*)?"),
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

# The site holds docs/ only. A link that leaves docs/ (a README section, a firmware page)
# works on a forge but not in the site: one to a README section goes to the site page that
# shows it (index, protocols, mega, layout include the README), any other becomes the path
# as code. Applied to the README where it is included and to every docs/ page.
DOCS = ROOT / "docs"
README_PAGES = {"": "index.md", "set-up": "index.md#set-up", "usage": "index.md#usage",
                "protocols-and-bench-files": "protocols.md", "run-file": "index.md#run-file",
                "a-real-arduino-mega": "mega.md", "layout": "layout.md"}
_LINK = re.compile(r"\[([^\]]+)\]\(((?!https?:|mailto:|#)[^)\s]+)\)")


def site_links(text: str, base: Path, page: Path, src: Path = DOCS) -> str:
    """``text``'s links (relative to folder ``base``) made right for the page ``page`` of the
    site built from ``src``."""
    def one(m: re.Match[str]) -> str:
        label, target = m.group(1), m.group(2)
        path, _, anchor = target.partition("#")
        where = (base / path).resolve() if path else None
        if where is None or not where.exists() or (where.is_relative_to(src) and base.resolve() == page.parent):
            return m.group(0)           # unchanged: the strict build checks it
        if where.is_relative_to(src):
            link = os.path.relpath(where, page.parent) + (f"#{anchor}" if anchor else "")
            return f"[{label}]({link})"
        if where == ROOT / "README.md":
            if anchor not in README_PAGES:
                return m.group(0)       # the strict build reports the unknown section
            return f"[{label}]({os.path.relpath(src / README_PAGES[anchor], page.parent)})"
        file = os.path.relpath(where, ROOT)
        shown = file + (f"#{anchor}" if anchor else "")
        return f"`{shown}`" if label.strip("`") in (file, shown, target) else f"{label} (`{shown}`)"

    return _LINK.sub(one, text)


def _include_read(app, relative_path: Path, parent_docname: str, content: list[str]) -> None:
    src = Path(app.srcdir).resolve()
    included = (src / relative_path).resolve()
    content[0] = site_links(content[0], included.parent, src / app.env.doc2path(app.env.docname, False), src)


def _source_read(app, docname: str, source: list[str]) -> None:
    src = Path(app.srcdir).resolve()
    page = src / app.env.doc2path(docname, False)
    source[0] = site_links(source[0], page.parent, page, src)


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
    app.connect("source-read", _source_read)
    app.connect("autodoc-process-signature", _dataclass_defaults)
    app.connect("include-read", _include_read)
    app.connect("missing-reference", _internal_reference)
