"""The set-up prints only what a user needs (issue 53 item 2): scripts/setup_env.sh keeps
the installer's output (uv's, or pip's where uv fails), setuptools' "Editable installation"
notes among it, out of sight unless the install fails (then it shows it whole), and says once
where the `demscale` command is and how a shell finds it; the docs that show `demscale`
commands say so too. The script runs on a copy of the repository's top with a stand-in
Python whose pip and uv only print (no index, well under a second)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

#: What setuptools prints during `pip install -e` (the block the issue quotes, shortened).
NOTE = "Editable installation: the editable install of this project uses a .pth hook"


def stand_in_python(path: Path, pip_fails: bool, uv_fails: bool = False) -> Path:
    """A `python3` that makes a venv (``-m venv DIR``) whose python runs a pip (and a uv)
    that prints setuptools' note to stderr and succeeds (or fails; uv alone fails with
    ``uv_fails``)."""
    uv = 'if [ "$2" = "uv" ]; then echo "uv: no index reachable" >&2; exit 1; fi\n'
    venv_python = f"""#!/bin/sh
{uv if uv_fails else ""}echo "running pip $*"
echo "!! {NOTE} !!" >&2
echo "********************************************************************************" >&2
exit {1 if pip_fails else 0}
"""
    path.write_text(
        "#!/bin/sh\n"
        '[ "$1" = "-m" ] && [ "$2" = "venv" ] || exit 2\n'
        'mkdir -p "$3/bin"\n'
        f"cat > \"$3/bin/python\" <<'EOS'\n{venv_python}EOS\n"
        'chmod +x "$3/bin/python"\n'
    )
    path.chmod(0o755)
    return path


def setup(
    tmp_path: Path, pip_fails: bool = False, uv_fails: bool = False, env: dict | None = None
) -> tuple[Path, callable]:
    repo = tmp_path / "repo"
    (repo / "scripts").mkdir(parents=True)
    shutil.copy(ROOT / "scripts" / "setup_env.sh", repo / "scripts")
    (repo / "pyproject.toml").write_text("[project]\nname = 'demscale'\n")
    python = stand_in_python(tmp_path / "python3", pip_fails, uv_fails)

    def run(again_with: dict | None = None) -> subprocess.CompletedProcess:
        """The set-up in ``repo``; ``again_with`` replaces ``env`` (the same repository,
        another mode)."""
        return subprocess.run(
            ["bash", "scripts/setup_env.sh"],
            cwd=repo,
            env={
                "PATH": "/usr/bin:/bin",
                "PYTHON": str(python),
                **(env or {} if again_with is None else again_with),
            },
            capture_output=True,
            text=True,
            timeout=60,
        )

    return repo, run


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_the_set_up_is_quiet_and_says_where_demscale_is(tmp_path):
    repo, run = setup(tmp_path)
    first = run()
    said = first.stdout + first.stderr
    assert first.returncode == 0, said
    assert NOTE not in said and "running pip" not in said and "*****" not in said
    assert "source .venv/bin/activate" in said and ".venv/bin/demscale" in said
    assert len(said.splitlines()) <= 4, said
    assert NOTE in (repo / ".venv" / "setup.log").read_text()  # kept, out of sight
    again = run()  # installed: nothing to say
    assert again.returncode == 0 and again.stdout + again.stderr == ""


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_a_failed_install_shows_pip_s_output(tmp_path):
    _, run = setup(tmp_path, pip_fails=True)
    failed = run()
    assert failed.returncode == 1
    assert NOTE in failed.stderr and "running pip" in failed.stderr
    assert "the install into ./.venv failed" in failed.stderr


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_pip_installs_where_uv_cannot(tmp_path):
    repo, run = setup(tmp_path, uv_fails=True)
    done = run()
    said = done.stdout + done.stderr
    assert done.returncode == 0, said
    assert "uv could not install" in done.stderr and "installing with pip" in done.stderr
    assert "uv: no index reachable" in (repo / ".venv" / "setup.log.uv").read_text()
    assert "running pip -m pip install --quiet -e" in (repo / ".venv" / "setup.log").read_text()
    assert (repo / ".venv" / ".demscale-installed").exists()


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
@pytest.mark.parametrize("uv_fails", [False, True])
def test_bytecode_is_compiled_at_install_unless_lazy(tmp_path, uv_fails):
    """By default every installed module is compiled (uv's --compile-bytecode; pip compiles
    by default); DEMSCALE_BYTECODE=lazy (scripts/test.sh) leaves it to the run (pip's
    --no-compile); any other value is refused naming the variable."""
    said = {}
    for mode in ("all", "lazy"):
        repo, run = setup(tmp_path / mode, uv_fails=uv_fails, env={"DEMSCALE_BYTECODE": mode})
        done = run()
        assert done.returncode == 0, done.stdout + done.stderr
        said[mode] = (repo / ".venv" / "setup.log").read_text()
    install = [ln for ln in said["all"].splitlines() if "-e" in ln.split()]
    lazy = [ln for ln in said["lazy"].splitlines() if "-e" in ln.split()]
    assert len(install) == len(lazy) == 1, said
    if uv_fails:
        assert "--no-compile" not in install[0] and "--no-compile" in lazy[0]
    else:
        assert "--compile-bytecode" in install[0] and "--compile-bytecode" not in lazy[0]
    # unset: all
    repo, run = setup(tmp_path / "default", uv_fails=uv_fails)
    assert run().returncode == 0
    default = [ln for ln in (repo / ".venv" / "setup.log").read_text().splitlines() if "-e" in ln]
    assert default == install, (default, install)


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_a_lazy_venv_is_compiled_when_all_is_asked_and_bad_modes_are_refused(tmp_path):
    repo, run = setup(tmp_path, env={"DEMSCALE_BYTECODE": "lazy"})
    assert run().returncode == 0
    assert (repo / ".venv" / ".demscale-installed").read_text().strip() == "lazy"
    assert "compileall" not in (repo / ".venv" / "setup.log").read_text()
    done = run(again_with={})  # the default mode
    assert done.returncode == 0 and "compiling the installed modules" in done.stdout
    assert "-m compileall -q -j 0 .venv/lib" in (repo / ".venv" / "setup.log").read_text()
    assert (repo / ".venv" / ".demscale-installed").read_text().strip() == "all"
    again = run(again_with={})  # compiled: nothing to say
    assert again.returncode == 0 and again.stdout + again.stderr == ""
    # refused when installed too; an empty value is the default
    bad = run(again_with={"DEMSCALE_BYTECODE": "some"})
    assert bad.returncode == 2, bad
    assert "DEMSCALE_BYTECODE must be 'all' or 'lazy', not 'some'" in bad.stderr
    empty = run(again_with={"DEMSCALE_BYTECODE": ""})
    assert empty.returncode == 0 and empty.stdout + empty.stderr == ""


def test_the_test_script_installs_lazily_and_writes_bytecode():
    text = (ROOT / "scripts" / "test.sh").read_text()
    assert "DEMSCALE_BYTECODE=lazy bash scripts/setup_env.sh" in text
    assert "unset PYTHONDONTWRITEBYTECODE" in text
    assert text.index("unset PYTHONDONTWRITEBYTECODE") < text.index("--collect-only")


@pytest.mark.parametrize("doc", ["docs/COMMAND_LINE.md", "docs/SERVICE.md"])
def test_the_docs_say_how_a_shell_finds_demscale(doc):
    text = (ROOT / doc).read_text()
    assert "demscale " in text
    assert "source .venv/bin/activate" in text and ".venv/bin/demscale" in text
