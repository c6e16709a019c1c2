"""MkDocs hooks of the documentation site (mkdocs.yml: ``hooks``), for what no option does.

- A link from a page to a repository file outside ``docs/`` (``../benchmarks/README.md``) works
  on GitHub but has no target on the site: there it becomes its link text.
- The notebook pages (mkdocs-jupyter) keep their links as written for Jupyter (``x.md``,
  ``y.ipynb``): on the site they point to the built pages (``x.html``, ``y.html``).
- MathJax, for the formulas of the notebooks' outputs, comes from a local copy: the MathJax 2
  that the ``jupyter-server-mathjax`` package installs is copied into ``site/assets/mathjax``,
  so that no page loads a script from the network.
- Files the notebooks write while they run in the build (the tutorial's HTML report) are copied
  next to the notebook pages, so that the tutorial's link to its report works.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path
from typing import Any

#: ``[text](target)``: the Markdown links of a page (images are left alone: ``(?<!!)``)
_LINK = re.compile(r"(?<!!)\[([^\]\n]+)\]\(([^()\s]+)\)")
#: a relative ``href`` in a built notebook page
_HREF = re.compile(r'href="(?![a-z][a-z0-9+.-]*:|#|/)([^"#]+)\.(?:md|ipynb)(#[^"]*)?"')
#: the parts of MathJax 2 left out of the copy (other output formats, languages, speech maps)
_MATHJAX_SKIP = ("jax/output/SVG", "extensions/a11y/mathmaps")
#: config/local/chaplygin.js (``?config=…,local/chaplygin``): the package ships the STIX-Web
#: fonts only (as Jupyter configures its MathJax); MathJax's default, the TeX fonts, would leave
#: accents and scripts misplaced
_MATHJAX_CONFIG = """MathJax.Hub.Config({
  "HTML-CSS": {availableFonts: [], preferredFont: null, webFont: "STIX-Web", imageFont: null}
});
MathJax.Ajax.loadComplete("[MathJax]/config/local/chaplygin.js");
"""


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    docs = Path(config["docs_dir"]).resolve()
    here = Path(page.file.abs_src_path).parent

    def unlink(match: re.Match[str]) -> str:
        target = match.group(2).split("#", 1)[0]
        if not target or re.match(r"[a-z][a-z0-9+.-]*:", target):
            return match.group(0)
        resolved = (here / target).resolve()
        return match.group(1) if docs not in resolved.parents and resolved.exists() else match.group(0)

    return _LINK.sub(unlink, markdown)


def on_post_page(output: str, page: Any, config: Any) -> str:
    if not page.file.src_uri.endswith(".ipynb"):
        return output
    return _HREF.sub(lambda m: f'href="{m.group(1)}.html{m.group(2) or ""}"', output)


def on_post_build(config: Any) -> None:
    import jupyter_server_mathjax

    site = Path(config["site_dir"])
    source = Path(jupyter_server_mathjax.__file__).parent / "static"

    def skip(folder: str, names: list[str]) -> list[str]:
        rel = Path(folder).relative_to(source).as_posix()
        left_out = [n for n in names if (Path(rel) / n).as_posix() in _MATHJAX_SKIP]
        if rel == "localization":
            left_out += [n for n in names if n != "en"]
        return left_out

    mathjax = site / "assets" / "mathjax"
    shutil.copytree(source, mathjax, ignore=skip, dirs_exist_ok=True)
    (mathjax / "config" / "local").mkdir(exist_ok=True)
    (mathjax / "config" / "local" / "chaplygin.js").write_text(_MATHJAX_CONFIG, encoding="utf-8")

    notebooks = Path(config["docs_dir"]) / "notebooks"
    for written in notebooks.glob("*.html"):
        shutil.copy2(written, site / "notebooks" / written.name)
