"""Every code block and command of README.md and docs/*.md, accounted for and run.

Each code block (fenced, or indented four spaces) is found, and each of its commands (and
each Python block) is classified by :data:`RULES`: a block or command no rule covers fails
the test, so that a new one is placed. What CI does (fast):

- every ``demscale`` command is parsed by the command's own argument parser (a wrong flag
  fails) and every example file it names exists;
- every Python block compiles and ruff finds no undefined name in it (``F821``: a snippet
  that uses a variable it never made);
- the quick commands (``--help``) run.

What runs them for real (minutes to tens of minutes: marked ``manual``, left out of CI):

    .venv/bin/python -m pytest -m manual tests/test_docs.py -p no:cacheprovider

which runs, in a temporary folder holding a copy of examples/, each document's runnable
blocks in order (the calibration example, its export, the study and run examples, the
README's Python snippets, the snapshot snippet, the service started and stopped, the main
job), each ``demscale`` command in a fresh shell that first does what README.md says
(``source .venv/bin/activate``). A few are never run here, each with its reason in
:data:`RULES` (the package index, a GPU, LIGGGHTS, hours of benchmark, the test suite
itself).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


@dataclass(frozen=True)
class Block:
    path: Path
    line: int
    lang: str  # "python", "bash", "" (fenced without a language) or "indented"
    text: str

    def __str__(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def code_blocks(path: Path) -> list[Block]:
    """The fenced blocks and the blocks indented four spaces (after a blank line) of a
    markdown file."""
    lines = path.read_text().splitlines()
    out, i = [], 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("```"):
            j = i + 1
            while not lines[j].startswith("```"):
                j += 1
            out.append(Block(path, i + 1, line[3:].strip(), "\n".join(lines[i + 1 : j])))
            i = j + 1
            continue
        if line.startswith("    ") and line.strip() and (i == 0 or not lines[i - 1].strip()):
            j = i
            while j < len(lines) and (lines[j].startswith("    ") or not lines[j].strip()):
                j += 1
            text = "\n".join(x[4:] for x in lines[i:j]).strip("\n")
            out.append(Block(path, i + 1, "indented", text))
            i = j
            continue
        i += 1
    return out


def commands(block: Block) -> list[str]:
    """The commands of a shell-like block: continuation lines joined, comments and the
    ``[optional]`` parts of a synopsis left out."""
    text = re.sub(r"\\\n\s*", " ", block.text)
    out = []
    for line in text.splitlines():
        line = re.sub(r"\s+#.*$", "", line).strip()
        line = re.sub(r"\s*\[[^\]]*\]", "", line).strip()
        if line and not line.startswith("#"):
            out.append(line)
    return out


# ------------------------------------------------------------------ what each one is
#: Blocks that are no code (formulas, a file layout, a report's table), by file and first
#: line: nothing to run.
NOT_CODE = [
    ("docs/PHYSICS.md", "dmax"),
    ("docs/PHYSICS.md", "1/E* ="),
    ("docs/PHYSICS.md", "d ± t(1 - a"),
    ("docs/PHYSICS.md", "K1, K2 ~ s^(2 - n)"),
    ("docs/SERVICE.md", "/                          attrs:"),
    ("docs/VALIDATION.md", "| run | particles"),
    ("docs/CALIBRATION.md", "F_pull ="),
]

#: How each command is treated, first match wins: (pattern, kind, how or why).
#: kind: "cli" (parsed in CI; run in the manual set), "help" (run in CI), "manual" (run
#: in the manual set only), "never" (not run by these tests: why).
RULES: list[tuple[str, str, str]] = [
    (r"^demscale study my_study\.json", "never", "the user's own spec (a placeholder)"),
    (r"^demscale study spec\.json .*--backend cuda", "never", "an NVIDIA GPU (gpu_bench.sh)"),
    (r"^demscale (study|run|calibrate|export|plan) ", "cli", "parsed; run in the manual set"),
    (r"^demscale (export-test|judge-liggghts) ", "cli", "parsed; LIGGGHTS runs them (manual)"),
    (r"^demscale (serve|worker)\b", "manual", "started, answers /healthz, stopped"),
    (r"^demscale job\b", "manual", "the main job (bash scripts/main_job.sh --exit)"),
    (r"^bash scripts/main_job\.sh", "manual", "the main job: about 12 minutes on 2 cores"),
    (r"^bash scripts/test\.sh", "never", "the test suite itself (CI runs exactly it)"),
    (r"^\.venv/bin/python -m pytest", "never", "the tests themselves"),
    (r"^pip install", "never", "needs the package index: scripts/check_install.sh does it"),
    (r"^source \.venv/bin/activate$", "never", "a shell's set-up (tests/test_setup_script.py)"),
    (r"^python -m service (api|worker)", "manual", "started, answers, stopped"),
    (r"^uvicorn --factory service\.app:create_app", "manual", "started, answers, stopped"),
    (r"^python -m benchmarks\.", "never", "a benchmark (minutes to hours; benchmarks/README)"),
    (r"^curl ", "never", "the main job's API running (tests/service/test_plans.py: the body)"),
    (r"^\(cd deck/s1 && liggghts", "never", "LIGGGHTS 3.8 (tests/test_liggghts_deck*.py)"),
    (r"^for s in .*liggghts -in", "never", "LIGGGHTS 3.8 (tests/test_liggghts_deck*.py)"),
    (r"^DEMSCALE_BACKEND=cuda", "never", "an NVIDIA GPU (scripts/gpu_bench.sh)"),
    (r"^engine\.", "never", "an NVIDIA GPU (scripts/gpu_bench.sh); names checked by ruff"),
]


def not_code(block: Block) -> bool:
    first = block.text.strip().splitlines()[0]
    name = str(block.path.relative_to(ROOT))
    return any(name == f and first.startswith(start) for f, start in NOT_CODE)


def rule(command: str) -> tuple[str, str]:
    for pattern, kind, why in RULES:
        if re.search(pattern, command):
            return kind, why
    raise LookupError(command)


def every_block() -> list[Block]:
    return [b for path in DOCS for b in code_blocks(path)]


def shell_blocks() -> list[Block]:
    return [b for b in every_block() if b.lang != "python" and not not_code(b)]


def python_blocks() -> list[Block]:
    return [b for b in every_block() if b.lang == "python"]


# ------------------------------------------------------------------ CI: fast checks
def test_every_block_and_command_is_accounted_for():
    unknown = []
    for b in shell_blocks():
        for c in commands(b):
            try:
                rule(c)
            except LookupError:
                unknown.append(f"{b}: {c}")
    assert not unknown, "commands no rule of tests/test_docs.py covers:\n" + "\n".join(unknown)
    assert python_blocks(), "no Python block found"


def _cli_commands() -> list[tuple[Block, str]]:
    return [(b, c) for b in shell_blocks() for c in commands(b) if rule(c)[0] == "cli"]


def test_a_rule_that_never_runs_comes_before_the_rule_that_would():
    # the specific "never" rules of demscale commands are matched before the general one
    assert rule("demscale study spec.json --out results/s --backend cuda")[0] == "never"
    assert rule("demscale study my_study.json --out results/mine --workers 4")[0] == "never"


@pytest.mark.parametrize(
    "block,command", _cli_commands(), ids=[f"{b}:{c[:40]}" for b, c in _cli_commands()]
)
def test_a_documented_command_parses_and_its_examples_exist(block, command):
    pytest.importorskip("rich")
    from demscale.cli import parser

    argv = shlex.split(command)[1:]
    if argv[0] in ("export-test", "judge-liggghts"):  # the deck engineer's subcommands
        pytest.importorskip("demscale.commands.deck")
    args = parser().parse_args(argv)  # a wrong flag exits 2 here
    for value in vars(args).values():
        for v in value if isinstance(value, list) else [value]:
            if isinstance(v, str) and v.startswith("examples/"):
                assert (ROOT / v).is_file(), f"{block}: {v} is not in the repository"


@pytest.mark.parametrize("block", python_blocks(), ids=str)
def test_a_python_block_compiles_and_uses_no_undefined_name(block, tmp_path):
    compile(block.text, str(block), "exec")
    src = tmp_path / "block.py"
    src.write_text(block.text)
    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")
    if ruff is None:
        pytest.skip("ruff is not installed")
    out = subprocess.run(
        [ruff, "check", "--no-cache", "--isolated", "--select", "F821", str(src)],
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, f"{block}:\n{out.stdout}"


def test_the_help_of_every_documented_command_runs(capsys):
    from demscale.cli import main

    for sub in ("study", "run", "calibrate", "export", "serve", "worker", "plan"):
        with pytest.raises(SystemExit) as e:
            main([sub, "--help"])
        assert e.value.code == 0
    assert "usage" in capsys.readouterr().out


# ------------------------------------------------------------------ manual: run them all
@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """A temporary folder with a copy of examples/, where the documented commands run as a
    user would run them from a clone (relative paths)."""
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def _fresh_shell_env() -> dict:
    """A new shell's environment: no PYTHONPATH, no virtual environment active."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    venv_bin = str(ROOT / ".venv" / "bin")
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep) if p != venv_bin)
    return env


def _run(command: str, cwd: Path, timeout: float, ok=(0,)) -> subprocess.CompletedProcess:
    """Run a documented command as a user would after the two set-up commands: a
    ``demscale`` command in a fresh shell that does what the README says (``source
    .venv/bin/activate``), where ``./.venv`` is the set-up's; anything else as given."""
    argv = shlex.split(command)
    env = _env()
    if argv[0] == "demscale":
        activate = ROOT / ".venv" / "bin" / "activate"
        if activate.is_file():
            argv = ["bash", "-c", f"source {shlex.quote(str(activate))} && {command}"]
            env = _fresh_shell_env()
        else:  # no set-up venv (an installed package): the interpreter running the tests
            argv = [sys.executable, "-m", "demscale", *argv[1:]]
    t0 = time.monotonic()
    out = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    print(f"{command}: exit {out.returncode}, {time.monotonic() - t0:.0f} s")
    assert out.returncode in ok, f"{command}\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
    return out


@pytest.mark.manual
@pytest.mark.timeout(3600)
def test_manual_the_command_blocks_run(workdir):
    """Every documented ``demscale`` command, in each document's order (the calibration
    before the exports of its law); the study example is the longest (a few minutes)."""
    done = set()
    order = sorted(
        _cli_commands(), key=lambda bc: ("export " in bc[1], "study " in bc[1], bc[0].line)
    )
    for _, c in order:
        if c in done or c.startswith(("demscale export-test", "demscale judge-liggghts")):
            continue
        done.add(c)
        t0 = time.monotonic()
        _run(c, workdir, 1800)
        if "calibrate " in c:  # issue 42: the calibration example in under two minutes
            assert time.monotonic() - t0 < 120, c


@pytest.mark.manual
@pytest.mark.timeout(3600)
@pytest.mark.parametrize("block", python_blocks(), ids=str)
def test_manual_a_python_block_runs(block, workdir):
    code = block.text
    path = workdir / "block.py"
    path.write_text(code)
    _run(f"{sys.executable} {path}", workdir, 3600)


#: The documented ways to start the API, as argv (the port set by the test).
SERVICE_STARTS = {
    "demscale serve": ["-m", "demscale", "serve", "--port", "{port}", "--data-dir", "var"],
    "python -m service api": ["-m", "service", "api"],
    "uvicorn --factory service.app:create_app": [
        "-m",
        "uvicorn",
        "--factory",
        "service.app:create_app",
        "--port",
        "{port}",
    ],
}


@pytest.mark.manual
@pytest.mark.timeout(600)
@pytest.mark.parametrize("command", list(SERVICE_STARTS))
def test_manual_the_service_starts_answers_and_stops(command, workdir):
    from tests.service.conftest import free_port, wait_healthy

    port = free_port()
    env = {**_env(), "DEMSCALE_PORT": str(port), "DEMSCALE_DATA_DIR": str(workdir / "var")}
    env["DEMSCALE_API_TOKEN"] = "docs-test-token-0123456789"
    argv = [sys.executable, *(a.format(port=port) for a in SERVICE_STARTS[command])]
    proc = subprocess.Popen(
        argv, cwd=workdir, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )
    try:
        wait_healthy(f"http://127.0.0.1:{port}", proc, 120, 0.5, command)
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(60)


@pytest.mark.manual
@pytest.mark.timeout(3600)
def test_manual_the_main_job_runs(workdir):
    """README's first command: the main job, its default study through the service, to
    its end (``--exit``); about 12 minutes on 2 cores."""
    shutil.copytree(ROOT / "scripts", workdir / "scripts")
    out = _run("demscale job --exit", workdir, 3600)
    assert "verdict" in out.stdout + out.stderr
