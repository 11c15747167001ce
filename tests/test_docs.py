"""The README and docs/: short README, links that resolve, nothing pointing outside the
repository, and (with mkdocs installed) a strict build of the site."""
from __future__ import annotations

import re
import subprocess
import sys

import pytest
from conftest import ROOT

LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
#: a link to a file outside docs/ (CHANGELOG.md, LICENSE): not a page of the site
_REPO_LINK = re.compile(r"\[([^\]]+)\]\((?!docs/|https?://)([^)\s]+)\)")


def site_index(readme: str) -> str:
    """docs/index.md, the site's home page: the README with its links made relative to docs/
    (a repository file outside docs/ named, not linked). ``python tests/test_docs.py`` writes it."""
    return _REPO_LINK.sub(lambda m: f"`{m.group(2)}`", readme).replace("](docs/", "](")


def tracked_text_files():
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if out.returncode != 0:
        pytest.skip("not a git checkout")
    return [ROOT / p for p in out.stdout.split() if p.endswith((".md", ".py", ".yaml", ".yml", ".toml", ".txt"))]


def test_readme_is_short_and_its_links_and_figures_exist():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 250
    targets = [t for t in LINK.findall(text) if "://" not in t]
    assert len([t for t in targets if t.endswith(".png")]) >= 3
    missing = [t for t in targets if not (ROOT / t).exists()]
    assert not missing, missing


def test_no_file_points_outside_the_repository():
    here = "tests/test_docs.py"
    offenders = [str(p.relative_to(ROOT)) for p in tracked_text_files()
                 if str(p.relative_to(ROOT)) != here and p.is_file()
                 and ("../shared/" in p.read_text(errors="replace") or "shared/brief" in p.read_text(errors="replace"))]
    assert not offenders, offenders


def test_every_docs_page_is_in_the_navigation():
    yaml = pytest.importorskip("yaml")
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    listed = {list(item.values())[0] for item in config["nav"]}
    pages = {str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs").rglob("*.md")}
    assert pages == listed
    assert config["strict"] is True


def test_the_site_builds_in_strict_mode(tmp_path):
    pytest.importorskip("mkdocs")
    pytest.importorskip("material")
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                         cwd=ROOT, capture_output=True, text=True, env={"NO_MKDOCS_2_WARNING": "1", "PATH": ""})
    assert out.returncode == 0, out.stderr[-3000:]
    assert (tmp_path / "site" / "results" / "index.html").is_file()


def test_the_site_home_page_is_the_readme():
    expected = site_index((ROOT / "README.md").read_text())
    assert (ROOT / "docs" / "index.md").read_text() == expected, "docs/index.md is stale: python tests/test_docs.py"


if __name__ == "__main__":  # write docs/index.md from the README
    (ROOT / "docs" / "index.md").write_text(site_index((ROOT / "README.md").read_text()))
