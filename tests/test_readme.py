"""The README's quick start and tour, run as written on small inputs.

Every ``hydromon`` command of the quick start and of "A five-minute tour" (the bash blocks and
the inline commands without a placeholder such as FILE), in the README's order, in a fresh
directory beside a link to ``recordings/``. What makes the inputs small, and nothing else, is
changed: durations are capped (``SHORT``; the servers, dashboard and foxglove, serve 3 s on a
free port), the tour's router listens on a free loopback port (its clients connect there
instead of 7447), ``sleep`` waits until ``watch --once`` is answered for every rig, and
``kill %N`` stops the background job N with SIGTERM. A later command on the bus (``$C``) that
says "with step 2's processes running" gets them started again as step 2 starts them, but for
the recorder (whose recording step 3 read and it would not overwrite). Each
command must exit 0 (the documented status of a trusted verdict), ``cmp`` must find the files
identical.
"""

from __future__ import annotations

import filecmp
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

from helpers import wait_for
from hydromon.bus.session import on_a_free_port

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "hydromon.cli"]
SHORT = {"demo": 4.0, "sim": 10.0, "dashboard": 3.0, "foxglove": 3.0}  # [s] the longest --duration here
SERVERS = ("dashboard", "foxglove")  # each serves on --port 0 (a free one) here
PLACEHOLDER = re.compile(r"\b[A-Z][A-Z_]+\b")  # FILE, COMMAND, ID, ...


def readme_commands() -> list[str]:
    """The quick start's and the tour's shell lines, in order: bash blocks line by line, and
    inline `hydromon ...` commands without a placeholder."""
    text = (ROOT / "README.md").read_text()
    start = text.index("```bash")  # the quick start's block
    tour = text.index("## A five-minute tour")
    end = text.index("\n## ", tour + 1)
    lines = []
    for m in re.finditer(r"```bash\n(.*?)```|`(hydromon [^`]*)`", text[start:end], re.S):
        if m.group(1) is not None:
            lines += [ln for ln in m.group(1).splitlines() if ln.strip()]
        elif not PLACEHOLDER.search(m.group(2)):
            lines.append(m.group(2))
    return lines


class Shell:
    """Just enough of a shell for the README's lines (see the module docstring)."""

    def __init__(self, cwd: Path, log):
        self.cwd, self.log = cwd, log
        self.vars: dict[str, str] = {}
        self.jobs: list[subprocess.Popen] = []
        self.endpoint: str | None = None
        self.background: list[str] = []  # the lines that started the jobs, to start them again
        self.phase = "step 2"  # then "stopped" (kill), then "again" (started again for a later step)
        self.env = {**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "200"}

    def run_line(self, line: str) -> None:
        for part in line.split(";"):
            words = shlex.split(part, comments=True)
            if not words:
                continue
            m = re.fullmatch(r"(\w+)=(.*)", words[0])
            if m and len(words) == 1:
                self.vars[m.group(1)] = m.group(2)
                continue
            background = words[-1] == "&"
            words = words[:-1] if background else words
            if background and self.phase == "step 2":
                self.background.append(line)
            # "with step 2's processes running"
            if "$C" in words and self.phase == "stopped" and not background:
                self.phase, self.jobs, self.endpoint = "again", [], None
                for again in self.background:
                    if shlex.split(again)[1] != "record":
                        self.run_line(again)
                self.wait_for_board(0.0)
            chain = [list(g) for g in _split(words, "&&")]
            for i, cmd in enumerate(chain):
                if not self.run(self.expand(cmd), background and i == len(chain) - 1):
                    break

    def expand(self, words: list[str]) -> list[str]:
        out = []
        for w in words:
            if w.startswith("$"):
                out += self.vars[w[1:]].split()
            else:
                out.append(w)
        if self.endpoint:
            out = [w.replace("tcp/127.0.0.1:7447", self.endpoint) for w in out]
        return out

    def run(self, words: list[str], background: bool) -> bool:
        name = words[0]
        if name == "sleep":
            self.wait_for_board(float(words[1]))
            return True
        if name == "kill":
            for job in words[1:]:
                self.stop(self.jobs[int(job.lstrip("%")) - 1])
            self.phase = "stopped" if self.phase == "step 2" else self.phase
            return True
        if name == "cmp":
            assert filecmp.cmp(self.cwd / words[1], self.cwd / words[2], shallow=False), words
            return True
        if name == "echo":
            return True
        assert name == "hydromon", words
        args = _shorter(words[1:])
        if args[0] == "router" and background:
            return self.start_router(args)
        if background:
            self.jobs.append(self.popen(args))
            return True
        t0 = time.monotonic()
        p = subprocess.run(CLI + args, cwd=self.cwd, env=self.env, capture_output=True, text=True, timeout=600)
        self.log(f"$ hydromon {shlex.join(args)}  -> {p.returncode} in {time.monotonic() - t0:.0f} s\n"
                 f"{p.stdout}{p.stderr}")
        assert p.returncode == 0, (args, p.stdout[-3000:], p.stderr[-3000:])
        return True

    def popen(self, args):
        name = args[0] + str(len(self.jobs))
        out = open(self.cwd / f"{name}.log", "wb")
        return subprocess.Popen(CLI + args, cwd=self.cwd, env=self.env, stdout=out, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL)

    def start_router(self, args) -> bool:
        def start(ep):
            p = self.popen([*args, "--listen", ep])
            log = self.cwd / f"{args[0]}{len(self.jobs)}.log"
            wait_for(lambda: "listening on" in log.read_text(errors="replace") or p.poll() is not None, 120,
                     "the router")
            if p.poll() is not None:
                raise RuntimeError(log.read_text(errors="replace"))
            return p

        p, self.endpoint = on_a_free_port(start)
        self.jobs.append(p)
        return True

    def wait_for_board(self, seconds: float) -> None:
        """``sleep N`` before ``watch --once``: at least N s (the rigs' first grades), then until
        the monitor answers for every rig (a cold machine compiles before it grades)."""
        time.sleep(min(seconds, 10.0))
        args = ["watch", "--once", "--json", *self.expand(["$C"])]

        def answered():
            p = subprocess.run(CLI + args, cwd=self.cwd, env=self.env, capture_output=True, text=True, timeout=120)
            return p.returncode == 0 and len(__import__("json").loads(p.stdout)["rigs"]) == 5

        wait_for(answered, 240, "watch --once to show five graded rigs", poll_s=2.0)

    def stop(self, p: subprocess.Popen) -> None:
        p.send_signal(signal.SIGTERM)
        assert p.wait(timeout=120) == 0, p.args

    def kill_all(self) -> None:
        for p in self.jobs:
            if p.poll() is None:
                p.kill()
                p.wait()


def _split(words, sep):
    group = []
    for w in words:
        if w == sep:
            yield group
            group = []
        else:
            group.append(w)
    yield group


def _shorter(args: list[str]) -> list[str]:
    """``args`` with the command's --duration capped at SHORT (added for a demo without one)."""
    cap = SHORT.get(args[0])
    if cap is None or "--to-mcap" in args:  # a run written to a file is offline and takes seconds
        return args
    args = list(args)
    if "--duration" in args:
        i = args.index("--duration") + 1
        args[i] = f"{min(float(args[i]), cap):g}"
    elif args[0] == "demo" or args[0] in SERVERS:  # a background sim runs until its kill
        args += ["--duration", f"{cap:g}"]
    if args[0] in SERVERS:
        args += ["--port", "0"]
    return args


def test_the_readme_commands_run(tmp_path):
    lines = readme_commands()
    # what the README promises to show: the demo, the bus tour, evaluate, audit and replay
    for needle in ("hydromon demo", "hydromon router &", "hydromon watch --once", "hydromon evaluate tour.mcap",
                   "hydromon evaluate g3.csv", "hydromon audit db.csv", "--direct --out replayed.jsonl", "cmp ",
                   "hydromon commission press.mcap"):
        assert any(needle in ln for ln in lines), needle
    for d in ("recordings", "examples"):  # the README runs from a clone's root
        (tmp_path / d).symlink_to(ROOT / d)
    out = []
    shell = Shell(tmp_path, out.append)
    try:
        for line in lines:
            if line.lstrip().startswith(("pip ", "python ")):  # installing and the test suite itself
                line = " ".join(part for part in line.split("&&") if part.strip().startswith("hydromon"))
            shell.run_line(line)
    finally:
        shell.kill_all()
        print("\n".join(out))
    assert (tmp_path / "tour.mcap").stat().st_size > 0 and (tmp_path / "audit-report" / "audit.md").exists()
