"""wsnloc.job_server: workflow scripts run in children forked from one pre-loaded process."""

import os
import resource
import subprocess
import sys
import textwrap
import threading
import time

import pytest

from conftest import ROOT
from wsnloc import job_server
from wsnloc.job_server import JobFailed, run_script, script_imports

forks = pytest.mark.skipif(not job_server.FORKS, reason="the job server forks on Linux only")


def write_script(path, body: str):
    path.write_text(textwrap.dedent(body))
    return path


def run_in_subprocess(code: str, **kwargs) -> subprocess.CompletedProcess:
    """`code` in a fresh interpreter (its own job server, its stderr captured)."""
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          timeout=120, **kwargs)


def test_script_imports_are_the_module_level_import_statements_once_each(tmp_path):
    a = write_script(tmp_path / "a.py", """\
        import json
        from pathlib import Path
        x = 1
        def f():
            import scipy.signal
        """)
    b = write_script(tmp_path / "b.py", "from pathlib import Path\nimport numpy as np, json\n")
    assert script_imports([a, b]) == ["import json", "from pathlib import Path", "import numpy as np, json"]


def test_the_workflow_scripts_imports_all_run(tmp_path):
    """What the server preloads for the workflow: every statement imports (none is skipped)."""
    statements = script_imports(sorted((ROOT / "workflow" / "scripts").glob("*.py")))
    assert any("wsnloc.report" in s for s in statements) and any("pandas" in s for s in statements)
    for statement in statements:
        exec(statement, {})


@forks
def test_a_job_runs_its_script_in_a_child_of_the_server_with_its_snakemake_object(tmp_path):
    out = tmp_path / "out.txt"
    script = write_script(tmp_path / "job.py", """\
        import os
        sm = snakemake
        with open(sm.output[0], "w") as f:
            f.write(f"{sm.params['text']} {sm.wildcards['run']} {os.getppid()}")
        """)
    run_script(script, [], input=[], output=[str(out)], params={"text": "hello"}, wildcards={"run": "run-01"},
               log=[])
    text, run, parent = out.read_text().split()
    assert (text, run) == ("hello", "run-01")
    assert int(parent) == job_server._server.process.pid != os.getpid()


@forks
def test_preloaded_modules_are_in_the_jobs_and_a_failing_statement_is_skipped(tmp_path):
    """The server imports while idle: a job forked after that finds the module loaded."""
    probe = write_script(tmp_path / "probe.py", """\
        import sys
        open(snakemake.output[0], "w").write(str("wsnloc.report.figures" in sys.modules))
        """)
    code = f"""\
        import time
        from wsnloc.job_server import run_script, start_server
        start_server(["import no_such_module_here", "from wsnloc.report import figures"])
        for _ in range(100):
            run_script({str(probe)!r}, [], output=[{str(tmp_path / 'loaded')!r}])
            if open({str(tmp_path / 'loaded')!r}).read() == "True":
                break
            time.sleep(0.1)
        print(open({str(tmp_path / 'loaded')!r}).read())
        """
    result = run_in_subprocess(code)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "True"


@forks
def test_a_failing_job_raises_naming_the_script_and_its_log_and_prints_its_traceback(tmp_path):
    script = write_script(tmp_path / "broken.py", "raise ValueError('no usable epoch in run-07')\n")
    code = f"""\
        from wsnloc.job_server import JobFailed, run_script
        try:
            run_script({str(script)!r}, [], log=["logs/broken.log"])
        except JobFailed as error:
            print(error)
        """
    result = run_in_subprocess(code)
    assert "broken.py exited with status 1" in result.stdout and "logs/broken.log" in result.stdout
    assert "ValueError: no usable epoch in run-07" in result.stderr


@pytest.mark.parametrize(("body", "message"), [
    ("import sys\nsys.exit(3)\n", "exited with status 3"),
    ("import os\nos._exit(4)\n", "exited with status 4"),
    ("import os, signal\nos.kill(os.getpid(), signal.SIGKILL)\n", "was killed by signal 9"),
])
@forks
def test_exit_status_and_signals_of_a_job_are_reported(tmp_path, body, message):
    script = write_script(tmp_path / "job.py", body)
    with pytest.raises(JobFailed, match=message):
        run_script(script, [])


@forks
def test_a_job_that_ends_normally_has_its_log_and_buffered_stdout_written(tmp_path):
    log = tmp_path / "job.log"
    script = write_script(tmp_path / "job.py", f"""\
        import sys
        from wsnloc.workflow import start_job
        log = start_job({str(log)!r}, "job")
        log.info("written")
        sys.stdout.write("out, no newline")
        """)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}   # stdout block-buffered
    result = run_in_subprocess(f"from wsnloc.job_server import run_script; run_script({str(script)!r}, [])", env=env)
    assert result.returncode == 0, result.stderr
    assert "written" in log.read_text()
    assert "out, no newline" in result.stderr          # a job's stdout goes to the server's stderr


@forks
def test_two_jobs_run_at_the_same_time(tmp_path):
    """Each job waits for the other's file: run one after the other, the first would time out."""
    script = write_script(tmp_path / "job.py", """\
        import time
        from pathlib import Path
        mine, other = map(Path, snakemake.params)
        mine.touch()
        deadline = time.monotonic() + 20
        while not other.exists():
            if time.monotonic() > deadline:
                raise TimeoutError("the other job did not run meanwhile")
            time.sleep(0.01)
        """)
    a, b = tmp_path / "a", tmp_path / "b"
    errors = []

    def job(params):
        try:
            run_script(script, [], params=params)
        except JobFailed as error:
            errors.append(error)

    threads = [threading.Thread(target=job, args=(p,)) for p in ([str(a), str(b)], [str(b), str(a)])]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=60)
    assert not errors and a.exists() and b.exists()


@forks
def test_the_jobs_cpu_time_counts_in_the_process_that_ran_them_once_it_has_exited(tmp_path):
    """The server is reaped at exit, and it reaped its children: `time snakemake` sees their CPU."""
    script = write_script(tmp_path / "burn.py", """\
        import time
        end = time.process_time() + 0.6
        while time.process_time() < end:
            pass
        """)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    result = run_in_subprocess(f"from wsnloc.job_server import run_script; run_script({str(script)!r}, [])")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert result.returncode == 0, result.stderr
    assert after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime >= 0.6


@forks
def test_a_server_that_died_is_started_again_for_the_next_job(tmp_path):
    out = tmp_path / "out"
    script = write_script(tmp_path / "job.py", "open(snakemake.output[0], 'a').write('x')\n")
    run_script(script, [], output=[str(out)])
    job_server._server.process.kill()
    job_server._server.process.wait()
    deadline = time.monotonic() + 10
    while job_server._server.pending and time.monotonic() < deadline:
        time.sleep(0.01)
    run_script(script, [], output=[str(out)])
    assert out.read_text() == "xx"


def test_off_linux_each_job_runs_in_a_fresh_interpreter(tmp_path, monkeypatch):
    monkeypatch.setattr(job_server, "FORKS", False)
    out = tmp_path / "out.txt"
    script = write_script(tmp_path / "job.py", """\
        import os
        open(snakemake.output[0], "w").write(snakemake.params["text"])
        """)
    run_script(script, [], output=[str(out)], params={"text": "fresh"})
    assert out.read_text() == "fresh"
    broken = write_script(tmp_path / "broken.py", "raise RuntimeError('boom')\n")
    with pytest.raises(JobFailed, match="broken.py exited with status 1"):
        run_script(broken, [])
