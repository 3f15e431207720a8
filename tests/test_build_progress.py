"""mk/povray-make.sh: the POV-Ray compile of `make`/`make demo` (about 7 minutes on two cores)
says how far it is and where its log is, instead of being silent (issue 33). Checked on a
small make project that compiles like automake prints (the compiler's full command lines)."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from harness.core.paths import REPO_ROOT

SCRIPT = REPO_ROOT / "mk" / "povray-make.sh"
N = 12

# The compile rule as automake writes it (the command on a line of its own ending in "&&\\",
# between its dependency-tracking lines), and one file compiled by a plain one-line rule.
MAKEFILE = """\
.PHONY: all
SRCS := $(foreach i,$(shell seq 1 {n}),f$(i).cpp)
all: prog
f{n}.o: f{n}.cpp
\tg++ -O0 -c -o $@ $<
%.o: %.cpp
\tdepbase=`echo $@ | sed 's|\\.o$$||'`;\\
\tg++ -DHAVE_CONFIG_H -I. -O0 -MT $@ -MD -MP -MF $$depbase.Tpo -c -o $@ $< &&\\
\tmv -f $$depbase.Tpo $$depbase.Po
prog: $(SRCS:.cpp=.o)
\tg++ -o $@ $^ {link}
"""


def project(tmp: Path, link: str = "") -> Path:
    d = tmp / "proj"
    d.mkdir()
    (d / "Makefile").write_text(MAKEFILE.format(n=N, link=link))
    for i in range(1, N + 1):
        (d / f"f{i}.cpp").write_text(f"int f{i}() {{ return {i}; }}\n" + ("int main() {}\n" if i == 1 else ""))
    return d


def run(d: Path, log: Path, step: int = 5) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(SCRIPT), str(d), "2", str(log), str(step)], capture_output=True, text=True,
                          timeout=120)


def test_counts_files_and_names_the_log(tmp_path):
    d, log = project(tmp_path), tmp_path / "build.log"
    p = run(d, log)
    assert p.returncode == 0, p.stderr
    lines = p.stderr.splitlines()
    pat = re.compile(rf"compiling POV-Ray: (\d+)/{N} files, \d+:\d\d elapsed \(log: {re.escape(str(log))}\)")
    counts = [int(pat.fullmatch(ln)[1]) for ln in lines]  # every line is a progress line
    assert counts == [0, 5, 10, N], lines                   # a line every 5 files and at the end
    # the compiler's own output went to the log only
    assert p.stdout == "" and "g++" not in p.stderr
    text = log.read_text()
    assert text.count(" -c -o ") == N and text.count("&&\\\n") == N - 1 and "g++ -o prog" in text
    # nothing left to compile: no counter at all, status 0
    p = run(d, log)
    assert p.returncode == 0 and p.stderr == "", p.stderr


def test_on_a_terminal_the_line_is_rewritten_in_place(tmp_path):
    if not shutil.which("script"):
        pytest.skip("needs script(1) (bsdutils) for a pseudo-terminal")
    d, log = project(tmp_path), tmp_path / "build.log"
    p = subprocess.run(["script", "-qec", f"bash {SCRIPT} {d} 2 {log} 5", "/dev/null"], capture_output=True,
                       timeout=120)  # bytes: text mode would turn each lone \r into a line break
    shown = p.stdout.decode().replace("\r\n", "\n")
    assert p.returncode == 0, shown
    updates = re.findall(rf"\rcompiling POV-Ray: (\d+)/{N} files", shown)
    assert [int(u) for u in updates] == list(range(0, N + 1)) + [N], shown  # every file, then the last line
    assert shown.rstrip().endswith(f"(log: {log})") and shown.count("\n") == 1, repr(shown)


def test_a_failed_compile_shows_the_log_and_keeps_makes_status(tmp_path):
    d, log = project(tmp_path), tmp_path / "build.log"
    (d / "f7.cpp").write_text("this is not C++\n")
    p = run(d, log)
    assert p.returncode == 2, p.stderr
    assert "compiling POV-Ray failed (make exit 2); the last 40 lines of " + str(log) in p.stderr
    assert "f7.cpp:1:1: error" in p.stderr  # the compiler's message, from the log
