"""mkdocs hook (mkdocs.yml `hooks:`): the math of the pages becomes MathML when the site is built.

pymdownx.arithmatex (generic mode) finds the math (`$...$` inline, `$$...$$` displayed, never in
code) and wraps it as `<span class="arithmatex">\\(...\\)</span>` or `<div class="arithmatex">\\[...\\]</div>`;
this hook replaces each with the MathML that latex2mathml (pinned in the `docs` extra) writes for it.
Browsers draw MathML themselves, so the site needs no JavaScript and no CDN, at build time or when
read. A formula latex2mathml cannot read fails the build, naming the page.
"""

from __future__ import annotations

import html
import re
from typing import Any

from latex2mathml.converter import convert

_MATH = re.compile(r'<(span|div) class="arithmatex">(.*?)</\1>', re.DOTALL)
_DELIMITERS = {"span": ("\\(", "\\)"), "div": ("\\[", "\\]")}


def _mathml(match: re.Match[str]) -> str:
    tag, text = match.group(1), html.unescape(match.group(2)).strip()
    opening, closing = _DELIMITERS[tag]
    if text.startswith(opening) and text.endswith(closing):
        text = text[len(opening):-len(closing)]
    return convert(text.strip(), display="block" if tag == "div" else "inline")


def on_page_content(html_text: str, page: Any, **_: Any) -> str:
    try:
        return _MATH.sub(_mathml, html_text)
    except Exception as exc:  # latex2mathml raises its own types; say which page held the formula
        raise RuntimeError(f"{page.file.src_uri}: a formula latex2mathml cannot convert: {exc}") from exc
