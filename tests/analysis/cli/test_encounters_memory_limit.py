"""``merge-irl encounters`` under a real memory limit (``RLIMIT_AS`` set in a child process once
its imports are done): running out of memory is one line naming the file, exit status 2, and
nothing written."""

import subprocess
import sys
import textwrap
from pathlib import Path

from ngsim_testdata import write_large_ngsim

ROOT = Path(__file__).resolve().parents[3]

#: The child: import the command, then allow only ``margin`` MiB of address space more than it
#: has (too little to hold the table of a ~30 MB file), then run the command line.
_CHILD = textwrap.dedent("""
    import resource, sys
    from analysis.cli.main import main
    import analysis.cli.commands.encounters
    with open("/proc/self/status") as fh:
        size = next(int(l.split()[1]) for l in fh if l.startswith("VmSize:")) * 1024
    limit = size + int(sys.argv[1]) * 2**20
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    sys.exit(main(sys.argv[2:]))
""")


def test_encounters_out_of_memory_is_one_line_and_exit_2(tmp_path):
    src = tmp_path / "trajectories-big.csv"
    rows = write_large_ngsim(src, 30)
    assert rows > 250_000 and src.stat().st_size > 25e6
    out = tmp_path / "out" / "enc.parquet"
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, "35", "encounters", str(src), "--out", str(out)],
        capture_output=True, text=True, cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
        timeout=300,
    )
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert len(lines) == 1, proc.stderr[-2000:]
    assert lines[0].startswith(f"merge-irl encounters: error: {src}: out of memory: ")
    assert "MB free" in lines[0] and "ulimit -v" in lines[0]
    assert proc.stdout == ""
    assert not out.parent.exists()
