"""The repository carries its own facts (issue 43): no tracked file sends its reader to a file
outside the repository, as a design-notes directory beside the checkout (``shared`` in the
checkout's parent) or a path of the machine it was written on (its work tree, a home
directory). The facts such notes held belong on the sources page (docs/reference/sources.md); a
fixture names files relative to the repository. (This file spells the patterns in pieces.)"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: written in pieces, so that this file does not match itself
MACHINE_PATH = re.compile("|".join([
    r"\.\./" + "shared",                 # the notes beside the checkout
    r"(?<![\w.])/" + r"work/",           # the machine's work tree
    r"(?<![\w.])/" + r"root/",           # a home directory
    r"(?<![\w.])/" + r"home/\w",
    r"(?<![\w.])/" + r"Users/\w",
]))


def machine_paths() -> list[str]:
    """``file:line: text`` of every line of a tracked file that names a path outside the
    repository (``git grep``, which reads the work tree's copy of each tracked text file)."""
    git = shutil.which("git")
    if git is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout: which files are tracked is git's to say")
    out = subprocess.run([git, "grep", "-n", "-I", "-P", MACHINE_PATH.pattern], cwd=ROOT,
                         capture_output=True, text=True)
    assert out.returncode in (0, 1), out.stderr     # 1: nothing found
    return [line[:200] for line in out.stdout.splitlines()
            if MACHINE_PATH.search(line.split(":", 2)[-1])]


def test_no_tracked_file_names_a_path_outside_the_repository() -> None:
    found = machine_paths()
    assert not found, ("these lines send the reader outside the repository (carry the fact "
                       "on docs/reference/sources.md, or name the file relative to the "
                       "repository):\n" + "\n".join(found))


@pytest.mark.parametrize(("line", "outside"), [
    ("# see " + "../" + "shared/docs/papers.md", True),
    ("transcribed in ``/" + "work/shared/docs/papers.md``", True),
    ('"command": "hil qualify /' + 'work/main/dut_profiles/x.toml"', True),
    ("cache in /" + "root/.cache", True),
    ("docs/reference/sources.md, [F] Table 2", False),
    ("hil run --out runs/step", False),
    ("a network/" + "work/flow", False),
])
def test_the_rule_tells_a_machine_path_from_a_repository_one(line: str, outside: bool) -> None:
    assert bool(MACHINE_PATH.search(line)) is outside
