"""The model reference (``docs/model/``) has a heading for every section that arcube cites.

arcube's README, ``--help`` texts, error messages, reports and docstrings cite the specification as
"MODEL.md 14.3". A clone has no specification, so ``docs/model/`` restates it with the same section
numbers: each section X.Y is a heading "X.Y ..." with the explicit id ``{#X.Y}``. This file checks

* that every section cited in ``src/``, in the README and in the docs pages is such a heading
  (ranges "16-17" and "15.2-15.4" and lists "8.2, 14.3" are expanded; a citation wrapped over two
  lines, or continued in a ``#`` comment, still counts);
* that the model pages number their headings consistently (id = number, no number twice) and that
  links into them name an id that exists;
* when the specification is present above the repository (``shared/spec/MODEL.md`` in a parent folder,
  as in the developers' checkout), that every numbered section of it has a heading with the same title.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
MODEL_PAGES = sorted((DOCS / "model").glob("*.md"))
# The developers' checkout keeps the specification in a "shared" folder beside (or above) the worktree.
SPEC = next(
    (d / "shared" / "spec" / "MODEL.md" for d in ROOT.parents if (d / "shared" / "spec" / "MODEL.md").exists()),
    ROOT.parent / "shared" / "spec" / "MODEL.md",
)

_NUM = r"\d+(?:\.\d+)?"
_REF = rf"{_NUM}(?:\s*[-–]\s*{_NUM})?"
_CITATION = re.compile(
    rf"(?:MODEL\.md`?\s*|model\s+§\s*|\[§)(?:\(\s*)?(?:sections?\s+)?(?P<refs>{_REF}(?:\s*(?:,|and)\s*{_REF})*)"
)
_HEADING = re.compile(
    r"^(?P<hashes>#{1,6})\s+(?P<num>\d+(?:\.\d+)?)\.?\s+(?P<title>.*?)\s*(?:\{#(?P<id>[^}\s]+)\})?\s*$"
)


def _expand(ref: str) -> list[str]:
    """'8.2' -> ['8.2']; '16-17' -> ['16', '17']; '15.2-15.4' -> ['15.2', '15.3', '15.4'].

    A range between subsections of different sections ('14.3-15.2') cannot be listed without the
    headings, so only its two ends are returned."""
    ends = [e.strip() for e in re.split(r"[-–]", ref)]
    if len(ends) == 1:
        return ends
    lo, hi = ends
    if "." not in lo and "." not in hi:
        return [str(k) for k in range(int(lo), int(hi) + 1)]
    if "." in lo and "." in hi and lo.split(".")[0] == hi.split(".")[0]:
        major = lo.split(".")[0]
        return [f"{major}.{k}" for k in range(int(lo.split(".")[1]), int(hi.split(".")[1]) + 1)]
    return [lo, hi]


def cited_sections(text: str) -> list[str]:
    """Every section number that ``text`` cites as 'MODEL.md X.Y', in order, ranges expanded."""
    # Join wrapped lines (and a citation continued on the next '#' comment line) into one.
    flat = re.sub(r"[ \t]*\n[ \t]*(?:#+[ \t]*)?", " ", text)
    out: list[str] = []
    for m in _CITATION.finditer(flat):
        for ref in re.split(r"\s*(?:,|and)\s*", m.group("refs")):
            out.extend(_expand(ref))
    return out


def model_headings() -> dict[str, tuple[Path, str, str | None]]:
    """Section number -> (page, title, explicit id) of every numbered heading of docs/model/."""
    found: dict[str, tuple[Path, str, str | None]] = {}
    for page in MODEL_PAGES:
        in_fence = False
        for line in page.read_text(encoding="utf-8").splitlines():
            if re.match(r"^\s*(```|~~~)", line):
                in_fence = not in_fence
            m = None if in_fence else _HEADING.match(line)
            if m:
                num = m.group("num")
                assert num not in found, f"section {num} is a heading twice: {found[num][0].name} and {page.name}"
                found[num] = (page, m.group("title"), m.group("id"))
    return found


HEADINGS = model_headings()


def _sources() -> list[Path]:
    return sorted(
        p for p in (ROOT / "src").rglob("*") if p.is_file() and p.suffix in {".py", ".md", ".txt", ".json", ".toml"}
    )


def _missing(citations: dict[str, list[str]]) -> list[str]:
    return [f"{where}: MODEL.md {num}" for where, nums in citations.items() for num in nums if num not in HEADINGS]


# --- the collector itself ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("the guards of MODEL.md 8.2 (crank angle)", ["8.2"]),
        ("(MODEL.md 14.3).", ["14.3"]),
        ("(MODEL.md 8.2-8.3, 12.2, 16).", ["8.2", "8.3", "12.2", "16"]),
        ("MODEL.md 16-17 and more", ["16", "17"]),
        ("MODEL.md 15.2-15.4); next", ["15.2", "15.3", "15.4"]),
        ("MODEL.md 13.1-13.2 says", ["13.1", "13.2"]),
        ("MODEL.md 3–6 (en dash)", ["3", "4", "5", "6"]),
        ("`MODEL.md` section 4, 7.2).", ["4", "7.2"]),
        ("`MODEL.md` sections 3-5", ["3", "4", "5"]),
        ("MODEL.md 15.5 and 18: holding", ["15.5", "18"]),
        ("the masses of MODEL.md\n    18.1 (links)", ["18.1"]),
        ("# masses of MODEL.md\n    # 18.1 in a comment", ["18.1"]),
        ("(MODEL.md 15.2, ``(16, 5)``: |", ["15.2"]),
        ("MODEL.md 10, item 10", ["10"]),
        ("MODEL.md 16's grading; MODEL.md's text", ["16"]),
        ("MODEL.md 14.3-15.2", ["14.3", "15.2"]),
        ("no citation: model.md, MODEL.md.", []),
        ("the guards of model §8.2 (crank angle)", ["8.2"]),
        ("(model §16-17, 19.5)", ["16", "17", "19.5"]),
        ("the masses of model\n    §18.1 (links)", ["18.1"]),
        ("see [§19.6](../model/part4-one-robot.md#19.6).", ["19.6"]),
    ],
)
def test_cited_sections_reads_numbers_ranges_and_lists(text: str, expected: list[str]) -> None:
    assert cited_sections(text) == expected


# --- every citation has a heading ------------------------------------------------------------------


def test_src_citations_are_headings_of_the_model_pages() -> None:
    """Every 'model §X.Y' in src/ (docstrings, help texts, error messages, report text) is a heading."""
    citations = {str(p.relative_to(ROOT)): cited_sections(p.read_text(encoding="utf-8")) for p in _sources()}
    total = sum(len(v) for v in citations.values())
    assert total >= 100, f"only {total} citations found in src/: the collector no longer reads them"
    missing = _missing(citations)
    assert not missing, "cited in src/ but no heading in docs/model/:\n" + "\n".join(missing)


def test_no_text_a_user_reads_cites_a_file_the_user_lacks() -> None:
    """The specification is not in the repository: src/ (help texts, messages, reports, docstrings), the
    README and the docs cite the docs' model pages ("model §X.Y", a link "[§X.Y](...)"), never "MODEL.md"."""
    pages = [*_sources(), ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]
    naming = [str(p.relative_to(ROOT)) for p in pages if "MODEL.md" in p.read_text(encoding="utf-8")]
    assert not naming, f"these cite MODEL.md, which a user does not have: {naming}"


def test_readme_and_docs_citations_are_headings_of_the_model_pages() -> None:
    pages = [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]
    citations = {str(p.relative_to(ROOT)): cited_sections(p.read_text(encoding="utf-8")) for p in pages}
    assert len(citations["README.md"]) >= 10, "the README's citations are no longer found"
    missing = _missing(citations)
    assert not missing, "cited but no heading in docs/model/:\n" + "\n".join(missing)


# --- the model pages' own structure ----------------------------------------------------------------


def test_model_headings_carry_their_number_as_id() -> None:
    """'### 14.3 Clearance {#14.3}': the id is the number, so model/<page>/#14.3 is a stable link."""
    bad = [f"{page.name}: {num} {title} has id {hid!r}" for num, (page, title, hid) in HEADINGS.items() if hid != num]
    assert not bad, "\n".join(bad)
    for num in HEADINGS:
        if "." in num:
            assert num.split(".")[0] in HEADINGS, f"subsection {num} without its section {num.split('.')[0]}"


def test_sections_1_to_22_are_all_there() -> None:
    """Parts I-V of the specification are sections 1 to 22, each a heading of its own."""
    majors = sorted(int(n) for n in HEADINGS if "." not in n)
    assert majors == list(range(1, 23)), majors


_LINK = re.compile(r"\]\((?P<target>[^)\s#]*\.md)#(?P<anchor>[^)\s]+)\)")


def test_links_into_the_model_pages_name_existing_ids() -> None:
    """A link such as (model/part2-buildable.md#14.3) points at a heading id that exists on that page."""
    ids: dict[Path, set[str]] = {}
    for num, (page, _title, hid) in HEADINGS.items():
        ids.setdefault(page.resolve(), set()).add(hid or num)
    bad = []
    for page in [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]:
        for m in _LINK.finditer(page.read_text(encoding="utf-8")):
            target = (page.parent / m.group("target")).resolve()
            if target.parent == (DOCS / "model").resolve() and m.group("anchor") not in ids.get(target, set()):
                bad.append(f"{page.relative_to(ROOT)}: ({m.group('target')}#{m.group('anchor')})")
    assert not bad, "links to a missing model section id:\n" + "\n".join(bad)


@pytest.mark.skipif(not SPEC.exists(), reason=f"no specification at {SPEC} (a clone has none)")
def test_every_section_of_the_specification_has_a_heading_with_its_title() -> None:
    spec: dict[str, str] = {}
    for line in SPEC.read_text(encoding="utf-8").splitlines():
        m = _HEADING.match(line)
        if m and len(m.group("hashes")) >= 2:
            spec[m.group("num")] = m.group("title")
    assert len(spec) >= 60, "the specification's numbered headings were not found"
    missing = sorted(set(spec) - set(HEADINGS), key=lambda n: [int(k) for k in n.split(".")])
    assert not missing, f"sections of {SPEC} without a heading in docs/model/: {missing}"
    renamed = [f"{n}: spec {spec[n]!r}, docs {HEADINGS[n][1]!r}" for n in spec if spec[n] != HEADINGS[n][1]]
    assert not renamed, "headings whose title differs from the specification's:\n" + "\n".join(renamed)


def test_the_default_mode_is_written_once() -> None:
    """House II: the default working mode has one home (arcube.model.modes.DEFAULT_MODE_TEXT); no other code
    spells the literal "+,+,+,+" (docstrings and messages may say it inside their text)."""
    import io
    import tokenize

    spelled = []
    for path in (ROOT / "src").rglob("*.py"):
        for tok in tokenize.generate_tokens(io.StringIO(path.read_text(encoding="utf-8")).readline):
            if tok.type == tokenize.STRING and tok.string.strip("'\"") == "+,+,+,+":
                spelled.append(f"{path.relative_to(ROOT)}:{tok.start[0]}")
    assert spelled == ["src/arcube/model/modes.py:15"], spelled
