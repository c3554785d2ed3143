"""The README's Python examples (the Python section's and the Dask subsection's) run as
written, from a copy of the repository's root (the first) or an empty folder (the second)."""

import re
import shutil

from conftest import REPO


def readme_python_example():
    """The first ```python block of the README's "Python" section."""
    text = (REPO / "README.md").read_text()
    section = text[text.index("\n## Python\n") :]
    return re.search(r"```python\n(.*?)```", section, re.DOTALL).group(1)


def test_readme_example_runs(tmp_path, monkeypatch):
    (tmp_path / "samples").mkdir()
    shutil.copy(REPO / "samples" / "jacksboro_fault.tif", tmp_path / "samples")
    monkeypatch.chdir(tmp_path)
    scope = {}
    exec(compile(readme_python_example(), "README.md", "exec"), scope)
    assert len(scope["rows"]) == 3 and scope["triangles"].shape[1] == 3
    for name in ["jacksboro.ezw", "copy.ezw", "xr.ezw"]:
        assert (tmp_path / name).stat().st_size > 0


def readme_dask_example():
    """The ```python block of the README's "Dask" subsection."""
    text = (REPO / "README.md").read_text()
    section = text[text.index("\n### Dask\n") :]
    return re.search(r"```python\n(.*?)```", section, re.DOTALL).group(1)


def test_readme_dask_example_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    scope = {"__name__": "__main__"}
    exec(compile(readme_dask_example(), "README.md", "exec"), scope)
    assert scope["corner"].shape == (1000, 834) and scope["whole"].shape == (3000, 2500)
