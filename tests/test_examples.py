"""csim examples: the packaged example cases are copied with their schema, and run."""
from __future__ import annotations

import tomllib
from pathlib import Path

import yaml
from conftest import CONFIGS, ROOT, assert_bad_input, invoke

from csim.io.examples import COPY_MODELINE, example_files


def test_every_config_is_an_example():
    assert sorted(example_files()) == sorted(p.relative_to(CONFIGS) for p in CONFIGS.rglob("*.yaml"))


def test_examples_are_copied_with_the_schema_and_run(tmp_path):
    out = tmp_path / "cases"
    result = invoke("examples", out)
    assert result.exit_code == 0, result.output
    assert (out / "csim-case.schema.json").is_file() and (out / "batch" / "accuracy.yaml").is_file()
    text = (out / "pendulum.yaml").read_text()
    assert text.splitlines()[0] == COPY_MODELINE
    assert yaml.safe_load(text)["mechanism"]["name"] == "pendulum"
    run = invoke("run", out / "pendulum.yaml", "--set", "simulation.t_end=0.05", "--set", "simulation.backend=python",
                 "-q", "-o", tmp_path / "p.h5")
    assert run.exit_code == 0, run.output


def test_examples_never_replace_a_file(tmp_path):
    (tmp_path / "pendulum.yaml").write_text("mine\n")
    assert_bad_input(invoke("examples", tmp_path), "would replace", "pendulum.yaml")
    assert (tmp_path / "pendulum.yaml").read_text() == "mine\n"
    assert not (tmp_path / "quick_return.yaml").exists()


def test_the_distribution_lists_every_package_and_ships_the_examples():
    """pyproject lists the packages by hand (configs/ is mapped to csim.examples): none is left out."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "csim").rglob("__init__.py")}
    assert found <= listed, found - listed
    assert config["package-dir"]["csim.examples"] == "configs"
    assert not [p for p in (ROOT / "csim").rglob("*.py") if not (p.parent / "__init__.py").exists()]
    assert Path(ROOT / config["package-dir"]["csim.examples.batch"]).is_dir()


def test_a_built_wheel_ships_every_example_and_copies_them(tmp_path):
    """From a wheel (not the source tree): csim.examples is a namespace package there, and the
    batch manifests' cases (../iftomm/...) must be in it."""
    import shutil
    import subprocess
    import sys
    import zipfile

    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name)
    for folder in ("csim", "configs"):
        shutil.copytree(ROOT / folder, src / folder, ignore=shutil.ignore_patterns("__pycache__"))
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                            str(tmp_path / "wheel"), str(src)], capture_output=True, text=True, timeout=300)
    assert build.returncode == 0, build.stderr[-2000:]
    (wheel,) = (tmp_path / "wheel").glob("*.whl")
    with zipfile.ZipFile(wheel) as archive:
        archive.extractall(tmp_path / "site")
    shipped = {p.relative_to(tmp_path / "site" / "csim" / "examples")
               for p in (tmp_path / "site" / "csim" / "examples").rglob("*.yaml")}
    assert shipped == {p.relative_to(CONFIGS) for p in CONFIGS.rglob("*.yaml")}
    script = ("import sys; from csim.case import json_schema; from csim.io.examples import copy_examples; "
              "copy_examples(sys.argv[1], json_schema())")
    copy = subprocess.run([sys.executable, "-c", script, str(tmp_path / "out")], capture_output=True, text=True,
                          cwd=tmp_path, env={"PYTHONPATH": str(tmp_path / "site"), "PATH": "/usr/bin:/bin"},
                          timeout=120)
    assert copy.returncode == 0, copy.stderr[-2000:]
    manifest = yaml.safe_load((tmp_path / "out" / "batch" / "iftomm.yaml").read_text())
    cases = [entry["case"] for entry in manifest["cases"]]
    assert len(cases) >= 5 and all((tmp_path / "out" / "batch" / case).is_file() for case in cases), cases
    assert (tmp_path / "out" / "iftomm" / "a04_bricard.yaml").is_file()
