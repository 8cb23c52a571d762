"""Every citation in the repository resolves to a file and a heading in the repository.

The code and the docs cite the project's own documents (docs/architecture.md "Conventions"):
docs/model.md by section (``docs/model.md §4``, optionally with a subsection title:
``docs/model.md §7 "Mechanics"``) and every other page by heading (``docs/decisions.md, "Stiff
strands"``, ``decisions.md, "Threads"``, ``decisions "Settling"``, ``docs/architecture.md "USD
stage"``; titles may run over two comment or docstring lines). Checked here, over every text file
git knows (tracked or untracked and not ignored; the gallery's data under docs/gallery/ left out):

- a section citation names a ``## N.`` heading of that page, and its title a ``###`` heading inside
  that section;
- a title citation names a ``##``/``###`` heading of that page, exactly (whitespace normalised);
- every ``docs/...md`` and ``docs/images/...png`` path exists, and so does every relative
  Markdown link target (with its ``#anchor``, as GitHub makes anchors from headings);
- nothing cites the retired specification and design documents.

Each failure names file:line and the citation. Runs in well under a second.
"""
from __future__ import annotations

import bisect
import os
import re
import subprocess
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
THIS = Path(__file__).resolve()
#: folders walked when git is not at hand (an unpacked sdist)
WALKED = ("wooddecay", "tests", "scripts", "benchmarks", "docs", "tools")
TEXT_SUFFIXES = {".py", ".md", ".toml", ".txt", ".cfg", ".ini", ".yml", ".yaml", ".json", ".js", ".usda",
                 ".csv", ".sh", ".rst", ""}

#: the retired documents: built from pieces so that this file does not cite them itself
RETIRED = ("SPEC" + ".md", "DESIGN" + ".md", "SPEC" + " §", "DESIGN" + ' "')

#: a page name as cited: ``docs/decisions.md``, ``decisions.md``, ```docs/decisions.md``` or a
#: Markdown link ``[decisions.md](decisions.md)``; bare ``decisions``/``limits`` as docs/model.md
#: and the code write them (the other bare names are too common a word to be a citation); not a
#: path that is itself a string literal (``"docs/gallery.md"``)
_PAGE = (r"""(?<![\w/.\-"'])""" r"(?:docs/)?(?:(?P<md>[a-z_]+)\.md|(?P<bare>decisions|limits)\b)"
         r"`{0,2}\]?(?:\([^)\s]*\))?")
#: a quoted title, double quotes (escaped inside Python strings or not) or single quotes
_TITLE = r"""(?:\\?"(?P<dq>[^"\\]{2,160}?)\\?"|(?<!\w)'(?P<sq>[^'\n]{2,160}?)'(?!\w))"""
#: a page, then (comma, colon or opening parenthesis) a title
TITLED = re.compile(_PAGE + r"(?P<sep>(?=[\s,:(])\s*[,:(]?\s*\(?\s*)" + _TITLE)
#: further titles of the same page: ``"A", "B" and "C"``
MORE = re.compile(r"\s*(?:,|;|\band\b|\bor\b)\s*(?:and\s+)?" + _TITLE)
#: a page, then a quote opening: a title citation must follow (else it is reported unparsed)
OPENER = re.compile(_PAGE + r"(?=[\s,:(])\s*[,:(]?\s*\(?\s*\\?\"")
#: a section citation: ``docs/model.md §4``, ``[model.md](model.md) §7 "Mechanics"``
SECTION = re.compile(r"(?<![\w/.-])(?:docs/)?(?P<md>[a-z_]+)\.md`{0,2}\]?(?:\([^)\s]*\))?\s*§\s*(?P<n>\d+)"
                     r"(?:\s+\\?\"(?P<title>[^\"\\]{2,160}?)\\?\")?")
#: a path into docs/ in any text
PATH = re.compile(r"(?<![\w/.-])docs/(?:[\w.-]+/)*[\w.-]+\.(?:md|png)\b")
#: a Markdown link or image target (not a URL)
LINK = re.compile(r"\]\((?P<target>[^)\s]+)\)")
HEADING = re.compile(r"^(?P<level>#{1,6})\s+(?P<text>.+?)\s*#*\s*$")


def repo_files() -> list[Path]:
    """The text files to scan: what git tracks plus untracked files it does not ignore."""
    try:
        out = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                             capture_output=True, text=True, timeout=30, check=True).stdout
        names = sorted({n for n in out.split("\0") if n})
    except (OSError, subprocess.SubprocessError):
        names = ["README.md", "CHANGELOG.md"]
        for top in WALKED:
            for dirpath, dirnames, filenames in os.walk(ROOT / top):
                dirnames[:] = [d for d in dirnames
                               if d not in ("node_modules", "__pycache__") and not d.startswith(".")]
                names += [str(Path(dirpath, f).relative_to(ROOT)) for f in filenames]
    files = []
    for name in names:
        path = ROOT / name
        if name.startswith("docs/gallery/") or path.resolve() == THIS or not path.is_file() or path.is_symlink():
            continue
        if path.suffix.lower() not in TEXT_SUFFIXES:
            continue
        files.append(path)
    return files


def read_text(path: Path) -> str | None:
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if b"\0" in data[:8192]:
        return None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def joined(text: str) -> tuple[str, list[int]]:
    """The lines of ``text`` joined by single spaces, each continuation line stripped of its
    indent and comment or quote marker (``#``, ``#:``, ``//``, ``*``, ``>``), so that a title
    broken over two lines reads as one; and the offset at which each line starts."""
    out, starts = [], []
    pos = 0
    for i, line in enumerate(text.split("\n")):
        if i:
            line = " " + re.sub(r"^\s*(?:#:?|//|\*|>)?\s*", "", line)
        starts.append(pos + (1 if i else 0))
        out.append(line)
        pos += len(line)
    return "".join(out), starts


def line_of(starts: list[int], offset: int) -> int:
    return bisect.bisect_right(starts, offset)


def norm(title: str) -> str:
    return re.sub(r"\s+", " ", title).strip()


@cache
def headings(docs: Path, page: str) -> tuple[tuple[int, str], ...]:
    """(level, text) of every heading of <docs>/<page>.md outside code fences; () if no such page."""
    path = docs / f"{page}.md"
    if not path.is_file():
        return ()
    out, fenced = [], False
    for line in path.read_text("utf-8").split("\n"):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        m = None if fenced else HEADING.match(line)
        if m:
            out.append((len(m["level"]), norm(m["text"])))
    return tuple(out)


def section_titles(docs: Path, page: str, n: int) -> set[str] | None:
    """The ``###`` titles inside section ``## n.`` of <docs>/<page>.md, or None if it has no such section."""
    inside, titles = False, set()
    for level, text in headings(docs, page):
        if level <= 2:
            if inside:
                break
            inside = level == 2 and re.match(rf"{n}\.(\s|$)", text) is not None
        elif inside and level == 3:
            titles.add(text)
    return titles if inside else None


def slug(text: str) -> str:
    """GitHub's anchor for a heading: lower case, markup and punctuation dropped, spaces to hyphens."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)
    text = re.sub(r"<[^>]+>", "", text).replace("&lt;", "").replace("&gt;", "").replace("&amp;", "")
    return re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")


@cache
def anchors(path: Path) -> frozenset[str]:
    seen: dict[str, int] = {}
    out = set()
    text = path.read_text("utf-8") if path.is_file() else ""
    fenced = False
    for line in text.split("\n"):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        m = None if fenced else HEADING.match(line)
        if m:
            base = slug(m["text"].strip())
            k = seen.get(base, 0)
            seen[base] = k + 1
            out.add(base if k == 0 else f"{base}-{k}")
    return frozenset(out)


def check_text(rel: str, text: str, base_dir: Path = ROOT, docs: Path = DOCS) -> list[str]:
    """Unresolved citations in ``text`` (the file ``rel``, its links relative to ``base_dir``;
    cited pages read from ``docs``), one message each: ``rel:line: ...``."""
    problems = []
    flat, starts = joined(text)

    def where(offset: int) -> str:
        return f"{rel}:{line_of(starts, offset)}"

    for needle in RETIRED:
        for m in re.finditer(re.escape(needle), text):
            problems.append(f"{rel}:{text.count(chr(10), 0, m.start()) + 1}: cites a retired document: {needle!r}")

    # section citations: docs/model.md §N ["Title"]
    for m in SECTION.finditer(flat):
        page, n = m["md"], int(m["n"])
        cite = norm(m.group(0))
        if not (docs / f"{page}.md").is_file():
            problems.append(f"{where(m.start())}: {cite}: no docs/{page}.md")
            continue
        titles = section_titles(docs, page, n)
        if titles is None:
            problems.append(f"{where(m.start())}: {cite}: docs/{page}.md has no heading '## {n}.'")
        elif m["title"] and norm(m["title"]) not in titles:
            problems.append(f"{where(m.start())}: {cite}: docs/{page}.md §{n} has no heading "
                            f"'### {norm(m['title'])}'")

    # title citations: docs/<page>.md, "Title" (and "More", "Titles")
    parsed = set()
    for m in TITLED.finditer(flat):
        if m["sq"] is not None and not re.search(r"\s", m["sep"]):
            continue                      # ``decisions.md's`` is a possessive, not a citation
        page = m["md"] or m["bare"]
        titles, end = [m["dq"] if m["dq"] is not None else m["sq"]], m.end()
        while (more := MORE.match(flat, end)):
            titles.append(more["dq"] if more["dq"] is not None else more["sq"])
            end = more.end()
        parsed.add(m.start())
        if not (docs / f"{page}.md").is_file():
            problems.append(f"{where(m.start())}: {norm(m.group(0))}: no docs/{page}.md")
            continue
        known = {text for level, text in headings(docs, page) if level in (2, 3)}
        for title in titles:
            if norm(title) not in known:
                problems.append(f"{where(m.start())}: docs/{page}.md \"{norm(title)}\": no such ## or ### heading "
                                f"in docs/{page}.md")
    for m in OPENER.finditer(flat):
        if m.start() not in parsed:
            problems.append(f"{where(m.start())}: unreadable citation (no closing quote?): "
                            f"{norm(flat[m.start():m.end() + 60])!r}")

    # paths into docs/
    for m in PATH.finditer(text):
        if not (ROOT / m.group(0)).is_file():
            problems.append(f"{rel}:{text.count(chr(10), 0, m.start()) + 1}: {m.group(0)}: no such file")

    # relative Markdown links (and their anchors)
    if rel.endswith(".md"):
        for m in LINK.finditer(text):
            target = m["target"]
            if re.match(r"[a-z][a-z0-9+.-]*:", target) or target.startswith("<"):
                continue
            path_part, _, anchor = target.partition("#")
            dest = (base_dir / path_part).resolve() if path_part else None
            line = text.count("\n", 0, m.start()) + 1
            if dest is not None and not dest.exists():
                problems.append(f"{rel}:{line}: link {target}: no such file")
            elif anchor:
                page = dest if dest is not None else (base_dir / Path(rel).name).resolve()
                if page.suffix == ".md" and anchor not in anchors(page):
                    problems.append(f"{rel}:{line}: link {target}: no heading with anchor #{anchor}")
    return problems


def test_every_citation_resolves():
    problems = []
    files = repo_files()
    assert ROOT / DECISIONS in files, f"{DECISIONS} is not among the scanned files"
    for path in files:
        text = read_text(path)
        if text is None:
            continue
        problems += check_text(str(path.relative_to(ROOT)), text, path.parent)
    assert not problems, f"{len(problems)} unresolved citation(s):\n" + "\n".join(problems)


# ---- the checker itself, on small texts against the real pages ----
# (the sample citations are assembled from pieces, so that a grep of the repository for citations,
# or this checker, does not take them for real ones)

BARE = "decis" + "ions"
DECISIONS, LIMITS, MODEL, ARCHITECTURE = (f"docs/{page}.md" for page in (BARE, "lim" + "its", "model", "architecture"))


def sample(text: str) -> str:
    return (text.replace("<D>", DECISIONS).replace("<L>", LIMITS).replace("<M>", MODEL)
            .replace("<A>", ARCHITECTURE).replace("<d>", BARE))


def test_checker_accepts_real_headings():
    text = sample('See <D>, "Stiff strands" and <L>, "A second of mechanics costs 15 s".\n'
                  '# (<D>, "Held pieces" and "Adaptive\n'
                  '# schedule"), <d> "Settling", <M> §7 "Mechanics", <M> §4;\n'
                  '<A> "Blender add-on"; <D>\'s one-way flow.\n')
    assert check_text("x.py", text) == []


def test_checker_rejects_renamed_headings():
    text = sample('a\n(<D>, "Convergence monitor: strain\n'
                  '# excess") and <d> "Open points"\n'
                  '<M> §42, <M> §7 "Speeds", <L>, "Single elements swing"\n'
                  'docs/nothing' '.md and docs/images/none' '.png\n')
    problems = check_text("x.py", text)
    assert any(p.startswith(f'x.py:2: {DECISIONS} "Convergence monitor: strain excess"') for p in problems), problems
    assert any(p.startswith(f'x.py:3: {DECISIONS} "Open points"') for p in problems), problems
    assert any("x.py:4:" in p and "§42" in p for p in problems), problems
    assert any("x.py:4:" in p and "'### Speeds'" in p for p in problems), problems
    assert any("x.py:4:" in p and '"Single elements swing"' in p for p in problems), problems
    assert sum("x.py:5:" in p and "no such file" in p for p in problems) == 2, problems
    assert len(problems) == 7, problems


def test_checker_rejects_retired_documents_and_broken_links():
    text = ("see " + RETIRED[0] + " and " + RETIRED[2] + "3\n"
            "[usage](usage.md#no-such-heading), [gone](gone.md), [ok](usage.md#blender-add-on)\n")
    problems = check_text("docs/x.md", text, DOCS)
    assert sum("docs/x.md:1:" in p and "retired" in p for p in problems) == 2, problems
    assert any("docs/x.md:2: link usage.md#no-such-heading" in p for p in problems), problems
    assert any("docs/x.md:2: link gone.md: no such file" in p for p in problems), problems
    assert len(problems) == 4, problems


def test_checker_sees_a_renamed_heading_in_a_page(tmp_path):
    """Renaming a heading in a scratch copy of docs/ turns the citations of it into failures."""
    scratch = tmp_path / "docs"
    scratch.mkdir()
    for page in (Path(DECISIONS).stem, Path(MODEL).stem):
        (scratch / f"{page}.md").write_text((DOCS / f"{page}.md").read_text("utf-8"), "utf-8")
    cite = sample('<D>, "Stiff strands"; <M> §7 "Speed"\n')
    assert check_text("x.py", cite, docs=scratch) == []
    for page, old, new in ((Path(DECISIONS).stem, "### Stiff strands\n", "### Stiff rods\n"),
                           (Path(MODEL).stem, "### Speed\n", "### Timings\n")):
        text = (scratch / f"{page}.md").read_text("utf-8")
        assert text.count(old) == 1
        (scratch / f"{page}.md").write_text(text.replace(old, new), "utf-8")
    headings.cache_clear()
    problems = check_text("x.py", cite, docs=scratch)
    assert len(problems) == 2 and all(p.startswith("x.py:1:") for p in problems), problems
