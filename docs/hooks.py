"""MkDocs hook (mkdocs.yml): the README is the site's home page, and CONTRIBUTING.md and
CHANGELOG.md are pages, read from the repository's root, where they live for GitHub and pip.

Their links are written for the repository (``docs/commands.md``, ``CONTRIBUTING.md``) and the
docs pages' for their folder (``../README.md``); on the site all of them are pages of one folder,
so the links are rewritten to that: the files stay the one copy, and ``mkdocs build --strict``
still checks that every link resolves.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
#: root file -> its page on the site
PAGES = {"README.md": "index.md", "CONTRIBUTING.md": "CONTRIBUTING.md", "CHANGELOG.md": "CHANGELOG.md"}
LINK = re.compile(r"\]\((?!https?://|#)([^)\s#]+)")


def on_files(files: Any, config: Any) -> Any:
    from mkdocs.structure.files import File

    for name, uri in PAGES.items():
        files.append(File.generated(config, uri, content=(ROOT / name).read_text(encoding="utf-8")))
    return files


def _site_target(target: str, page_in_root: bool) -> str:
    if page_in_root:
        if target in PAGES:
            return PAGES[target]
        return target.removeprefix("docs/")
    if target.startswith("../") and target[3:] in PAGES:
        return PAGES[target[3:]]
    return target


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    in_root = page.file.src_uri in PAGES.values() and page.file.generated_by is not None
    return LINK.sub(lambda m: "](" + _site_target(m.group(1), in_root), markdown)
