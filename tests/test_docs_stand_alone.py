"""The repository's text stands on its own: no file of thermonet/, tests/, benchmarks/,
examples/, docs/, scenes/, meshes/ or the README cites a file outside the repository (the folder beside it, a
private specification's sections) or a tracker issue a reader cannot see. Theory is cited as
docs/theory.md §n.m, which this test also checks exists for every section cited."""

import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FOLDERS = ("thermonet", "tests", "benchmarks", "examples", "docs", "scenes", "meshes")
TEXT = (".py", ".md", ".toml", ".txt", ".cfg", ".sh", ".json", ".ini", ".yaml", ".yml")

#: what a reader outside the project's own tree cannot follow (written so as not to match itself)
OUTSIDE = {
    "a path beside the repository": re.compile(r"\.\./shar" r"ed"),
    "a section of a private specification": re.compile(r"\bspec(?:-heat)?(?:\.md)? *§", re.I),
    "a private specification file": re.compile(r"\bspec(?:-heat)?\.m" r"d\b", re.I),
    "a tracker issue": re.compile(r"\b(?:issue|issues|pr|pull request) +#?\d+\b", re.I),
    "a tracker number": re.compile(r"(?<![\w&#/])#\d+\b(?![\w-])"),
}


def _text_files():
    paths = [os.path.join(ROOT, "README.md")]
    for folder in FOLDERS:
        for base, dirs, files in os.walk(os.path.join(ROOT, folder)):
            dirs[:] = [d for d in dirs if d != "__pycache__" and not d.startswith(".")]
            paths += [os.path.join(base, f) for f in files if f.endswith(TEXT)]
    return paths


def test_no_reference_outside_the_repository_or_to_tracker_issues():
    hits = []
    for path in _text_files():
        with open(path, encoding="utf-8", errors="replace") as f:
            for number, line in enumerate(f, 1):
                for what, pattern in OUTSIDE.items():
                    if pattern.search(line):
                        hits.append(f"{os.path.relpath(path, ROOT)}:{number}: {what}: {line.strip()[:100]}")
    assert not hits, "\n".join(hits)


@pytest.mark.parametrize("pattern, text", [
    ("a path beside the repository", "see " + "../" + "shared/notes"),
    ("a section of a private specification", "(spec" + " §2.1)"),
    ("a section of a private specification", "spec-heat" + " §1"),
    ("a private specification file", "spec-heat" + ".md"),
    ("a tracker issue", "as in issue" + " 28"),
    ("a tracker number", "fixed in " + "#" + "28."),
])
def test_the_guard_finds_each_kind(pattern, text):
    assert OUTSIDE[pattern].search(text)


def test_every_cited_theory_section_exists():
    with open(os.path.join(ROOT, "docs", "theory.md"), encoding="utf-8") as f:
        headings = set(re.findall(r"^#{2,3} (\d+(?:\.\d+)?)\.? ", f.read(), re.M))
    cited = re.compile(r"docs/theory\.md((?: *§\d+(?:\.\d+)?(?:[–-]\d+(?:\.\d+)?)?,?)+)")
    missing = []
    for path in _text_files():
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read()
        for match in cited.finditer(text):
            for section in re.findall(r"§(\d+(?:\.\d+)?)", match.group(1)):
                if section not in headings:
                    missing.append(f"{os.path.relpath(path, ROOT)}: §{section}")
    assert not missing, missing
