"""Links of README.md and docs/*.md: relative file targets exist, and #anchors name a heading.

Pure Python, no navzoo import. Anchors follow GitHub's heading slugs (github-slugger): the heading's
rendered text, lowercased, with every character that is not a letter, mark, number, connector (``_``),
hyphen or space removed, and each space turned into a hyphen; a repeated slug gets ``-1``, ``-2``, ...
"""

from __future__ import annotations

import re
import unicodedata
from functools import cache
from pathlib import Path
from urllib.parse import unquote

import pytest

ROOT = Path(__file__).resolve().parent.parent

FENCE = re.compile(r"^\s*(`{3,}|~{3,})")  # any indent: fences nest in list items
ATX = re.compile(r"^\s{0,3}(#{1,6})(?:\s+(.*?))?\s*$")
CODE_SPAN = re.compile(r"(`+)(.+?)\1")
# [text](target) or ![alt](target), with an optional "title"; the text may hold one level of [...]
LINK = re.compile(r"!?\[((?:[^\[\]]|\[[^\[\]]*\])*)\]\(\s*<?([^)\s>]*)>?(?:\s+\"[^\"]*\")?\s*\)")
SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


def markdown_files() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) of the lines outside fenced code blocks."""
    out = []
    fence = None
    for number, line in enumerate(text.splitlines(), 1):
        m = FENCE.match(line)
        if fence is None:
            if m:
                fence = m.group(1)
                continue
            out.append((number, line))
        elif m and m.group(1)[0] == fence[0] and len(m.group(1)) >= len(fence) and not line.strip()[len(m.group(1)):]:
            fence = None
    return out


def heading_text(raw: str) -> str:
    """The text GitHub renders for an ATX heading's content (inline markup dropped)."""
    text = re.sub(r"\s+#+\s*$", "", raw.strip())  # closing hashes
    if re.fullmatch(r"#+", text):
        return ""
    parts = []
    pos = 0
    for m in CODE_SPAN.finditer(text):  # code spans keep their content verbatim
        parts.append(_strip_inline(text[pos:m.start()]))
        parts.append(m.group(2).strip())
        pos = m.end()
    parts.append(_strip_inline(text[pos:]))
    return "".join(parts)


def _strip_inline(text: str) -> str:
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)  # links and images: their text
    text = re.sub(r"<[^>]+>", "", text)  # HTML tags
    text = re.sub(r"(\*{1,3})(\S(?:.*?\S)?)\1", r"\2", text)  # *emphasis*, **strong**
    return text.replace("\\", "")


def slug(text: str) -> str:
    """github-slugger: lowercase; keep letters, marks, numbers, ``_``, ``-`` and spaces; spaces -> ``-``."""
    kept = []
    for ch in text.lower():
        cat = unicodedata.category(ch)
        if ch in "- " or cat[0] in "LMN" or cat == "Pc":
            kept.append(ch)
    return "".join(kept).replace(" ", "-")


def anchors_of_text(text: str) -> set[str]:
    seen: dict[str, int] = {}
    anchors = set()
    for _, line in prose_lines(text):
        m = ATX.match(line)
        if not m:
            continue
        base = slug(heading_text(m.group(2) or ""))
        if base in seen:
            seen[base] += 1
            anchor = f"{base}-{seen[base]}"
        else:
            seen[base] = 0
            anchor = base
        anchors.add(anchor)
    return anchors


@cache
def anchors_of(path: Path) -> frozenset[str]:
    return frozenset(anchors_of_text(path.read_text(encoding="utf-8")))


def prose_blocks(text: str) -> list[tuple[int, str]]:
    """(first line number, text) of the runs of consecutive prose lines that a link may span: a paragraph or list
    item wrapped over several lines. Blank lines, code fences, headings and table rows end a run (a table row and a
    heading are runs of their own)."""
    blocks: list[tuple[int, list[str]]] = []
    last = None
    for number, line in prose_lines(text):
        single = line.lstrip().startswith("|") or ATX.match(line) is not None
        if not line.strip():
            last = None
            continue
        if last is None or number != last + 1 or single or blocks[-1][1][-1].lstrip().startswith(("|", "#")):
            blocks.append((number, [line]))
        else:
            blocks[-1][1].append(line)
        last = number
    return [(start, "\n".join(lines)) for start, lines in blocks]


def links_of_text(text: str) -> list[tuple[int, str]]:
    """(line number, target) of every markdown link outside code blocks and code spans; a link whose text is
    wrapped over lines counts at the line where it starts."""
    out = []
    for start, block in prose_blocks(text):
        block = CODE_SPAN.sub(lambda m: "\n" * m.group(0).count("\n"), block)  # keep the line count
        for m in LINK.finditer(block):
            out.append((start + block.count("\n", 0, m.start()), m.group(2)))
    return out


def broken_links(path: Path) -> list[str]:
    problems = []
    for number, target in links_of_text(path.read_text(encoding="utf-8")):
        where = f"{path.relative_to(ROOT)}:{number}: ({target})"
        if not target or SCHEME.match(target):  # http(s):, mailto:, ...
            continue
        file_part, _, anchor = target.partition("#")
        dest = (path.parent / unquote(file_part)).resolve() if file_part else path
        if not dest.exists():
            problems.append(f"{where} no such file: {dest.relative_to(ROOT) if dest.is_relative_to(ROOT) else dest}")
            continue
        if anchor and dest.suffix == ".md" and dest.is_file():
            if unquote(anchor) not in anchors_of(dest):
                problems.append(f"{where} no heading with anchor #{anchor} in {dest.relative_to(ROOT)}")
    return problems


@pytest.mark.parametrize(
    ("heading", "anchor"),
    [
        ("Physics-based pedestrians (AMP)", "physics-based-pedestrians-amp"),
        ("Runs 17–18: more training did not help (2026-11-26, twentieth session)",
         "runs-1718-more-training-did-not-help-2026-11-26-twentieth-session"),
        ("A speed cap of 1.0 for diffusion targets (2026-11-28)", "a-speed-cap-of-10-for-diffusion-targets-2026-11-28"),
        ("Ten held-out scenes (2026-12-03/04, device and 2-core AMD VM)",
         "ten-held-out-scenes-2026-12-0304-device-and-2-core-amd-vm"),
        ("The trajectory diffusion model (`navzoo/agents/diffusion/`)", "the-trajectory-diffusion-model-navzooagentsdiffusion"),
        ('Physics pedestrians (`human_model="amp"`)', "physics-pedestrians-human_modelamp"),
        ("Walkers for the physics bodies' targets (2026-12-06, 2-core VM; not kept)",
         "walkers-for-the-physics-bodies-targets-2026-12-06-2-core-vm-not-kept"),
        ("Doors in 15 % of the patches + more → less — done, 1.5×", "doors-in-15--of-the-patches--more--less--done-15"),
        ("**Bold** and [a link](x.md) and *emphasis*", "bold-and-a-link-and-emphasis"),
        ("Ünïcode Straße", "ünïcode-straße"),
    ],
)
def test_slug(heading, anchor):
    assert slug(heading_text(heading)) == anchor


def test_duplicate_headings_and_code_blocks():
    text = "# A\n\n## Use\n\n```bash\n# Use\n```\n\n### Use\n\n#### Use ####\n"
    assert anchors_of_text(text) == {"a", "use", "use-1", "use-2"}


def test_links_skip_code():
    text = "[a](a.md) `[b](b.md)`\n```\n[c](c.md)\n```\n~~~\n[d](d.md)\n~~~\n![e](img/e.png \"t\") [f](<f.md#x>)\n"
    text += "- item\n    ```bash\n    [g](g.md)\n    ```\n"
    assert links_of_text(text) == [(1, "a.md"), (8, "img/e.png"), (8, "f.md#x")]


def test_links_wrapped_over_lines():
    text = "Some text, see [a long\n  title](a.md#x) and\n[b](b.md).\n\n| [c](c.md) |\n| [d\n\n[e\ntext](e.md)\n"
    assert links_of_text(text) == [(1, "a.md#x"), (3, "b.md"), (5, "c.md"), (8, "e.md")]


def test_docs_links():
    problems = [p for path in markdown_files() for p in broken_links(path)]
    assert not problems, f"{len(problems)} broken link(s):\n" + "\n".join(problems)
