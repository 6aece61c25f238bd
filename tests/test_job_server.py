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
from wsnloc.job_server import JobFailed, JobServer, script_imports

forks = pytest.mark.skipif(not job_server.FORKS, reason="the job server forks on Linux only")


def write_script(path, body: str):
    path.write_text(textwrap.dedent(body))
    return path


def run_in_subprocess(code: str, **kwargs) -> subprocess.CompletedProcess:
    """`code` in a fresh interpreter (a job server of its own, its output captured)."""
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          timeout=120, **kwargs)


@pytest.fixture
def server():
    """A job server of this test process, preloading nothing, stopped after the test."""
    jobs = JobServer([])
    yield jobs
    if jobs._client is not None:
        jobs._client.close()


def test_script_imports_are_the_module_level_import_statements_once_each(tmp_path):
    a = write_script(tmp_path / "a.py", """\
        import json
        from pathlib import Path
        x = 1
        def f():
            import scipy.signal
        """)
    b = write_script(tmp_path / "b.py", "from pathlib import Path\nimport numpy as np, json\n")
    broken = write_script(tmp_path / "broken.py", "import os\ndef (:\n")
    assert script_imports([a, broken, b]) == ["import json", "from pathlib import Path", "import numpy as np, json"]


def test_the_workflow_scripts_imports_all_run():
    """What the server preloads for the workflow: every statement imports (none is skipped)."""
    statements = script_imports(sorted((ROOT / "workflow" / "scripts").glob("*.py")))
    assert any("wsnloc.report" in s for s in statements) and any("pandas" in s for s in statements)
    for statement in statements:
        exec(statement, {})


@forks
def test_a_job_runs_its_script_in_a_child_of_the_server_with_its_snakemake_object(tmp_path, server):
    out = tmp_path / "out.txt"
    script = write_script(tmp_path / "job.py", """\
        import os, sys
        sm = snakemake
        with open(sm.output[0], "w") as f:
            f.write(f"{sm.params['text']} {sm.wildcards['run']} {sm.threads} {sys.argv[0]} {sys.path[0]} "
                    f"{os.environ['OPENBLAS_NUM_THREADS']} {os.getppid()}")
        """)
    server.run(script, input=[], output=[str(out)], params={"text": "hello"}, wildcards={"run": "run-01"}, log=[])
    text, run, threads, argv0, path0, blas, parent = out.read_text().split()
    assert (text, run, threads, argv0, path0, blas) == ("hello", "run-01", "1", str(script), str(tmp_path), "1")
    assert int(parent) == server._client.process.pid != os.getpid()


@forks
def test_preloaded_modules_are_in_the_jobs_and_a_failing_statement_is_skipped(tmp_path):
    """The server imports while idle: a job forked after that finds the module loaded."""
    probe = write_script(tmp_path / "probe.py", """\
        import sys
        open(snakemake.output[0], "w").write(str("wsnloc.report.figures" in sys.modules))
        """)
    loaded = tmp_path / "loaded"
    code = f"""\
        import time
        from wsnloc.job_server import JobServer
        jobs = JobServer(["import no_such_module_here", "from wsnloc.report import figures"])
        for _ in range(300):
            jobs.run({str(probe)!r}, output=[{str(loaded)!r}])
            if open({str(loaded)!r}).read() == "True":
                break
            time.sleep(0.1)
        print(open({str(loaded)!r}).read())
        """
    result = run_in_subprocess(code)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "True"


@forks
def test_a_failing_job_raises_naming_the_script_and_its_log_and_prints_its_traceback(tmp_path):
    script = write_script(tmp_path / "broken.py", "raise ValueError('no usable epoch in run-07')\n")
    code = f"""\
        from wsnloc.job_server import JobFailed, JobServer
        try:
            JobServer([]).run({str(script)!r}, log=["logs/broken.log"])
        except JobFailed as error:
            print(error)
        """
    result = run_in_subprocess(code)
    assert "broken.py exited with status 1" in result.stdout and "logs/broken.log" in result.stdout
    assert "ValueError: no usable epoch in run-07" in result.stderr


@pytest.mark.parametrize(("body", "message"), [
    ("import sys\nsys.exit(3)\n", "exited with status 3"),
    ("import sys\nsys.exit('fatal: no usable epoch')\n", "exited with status 1"),
    ("import os\nos._exit(4)\n", "exited with status 4"),
    ("import os, signal\nos.kill(os.getpid(), signal.SIGKILL)\n", "was killed by signal 9"),
])
@forks
def test_exit_status_and_signals_of_a_job_are_reported(tmp_path, server, body, message):
    script = write_script(tmp_path / "job.py", body)
    with pytest.raises(JobFailed, match=message):
        server.run(script)


@forks
def test_an_exit_message_is_printed_as_python_prints_it(tmp_path):
    script = write_script(tmp_path / "job.py", "import sys\nsys.exit('fatal: no usable epoch')\n")
    result = run_in_subprocess(f"""\
        from wsnloc.job_server import JobFailed, JobServer
        try:
            JobServer([]).run({str(script)!r})
        except JobFailed:
            pass
        """)
    assert "fatal: no usable epoch" in result.stderr


@forks
def test_a_job_whose_snakemake_object_does_not_unpickle_fails_alone(tmp_path, server):
    """A namespace that pickles in the client but not in the child (a class of a module only
    this process can import) fails its own job, with a traceback; the server and the next job
    are unaffected."""
    (tmp_path / "only_here").mkdir()
    (tmp_path / "only_here" / "only_here.py").write_text("class Value:\n    pass\n")
    script = write_script(tmp_path / "job.py", "open(snakemake.output[0], 'w').write('ran')\n")
    sys.path.insert(0, str(tmp_path / "only_here"))
    try:
        import only_here
        with pytest.raises(JobFailed, match="job.py exited with status 1"):
            server.run(script, params=[only_here.Value()], output=[str(tmp_path / "never")])
    finally:
        sys.path.remove(str(tmp_path / "only_here"))
        sys.modules.pop("only_here", None)
    server.run(script, output=[str(tmp_path / "out")])
    assert (tmp_path / "out").read_text() == "ran" and not (tmp_path / "never").exists()


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
    result = run_in_subprocess(f"from wsnloc.job_server import JobServer; JobServer([]).run({str(script)!r})", env=env)
    assert result.returncode == 0, result.stderr
    assert "written" in log.read_text()
    assert "out, no newline" in result.stderr          # a job's stdout goes to the server's stderr


@forks
def test_two_jobs_run_at_the_same_time(tmp_path, server):
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
            server.run(script, params=params)
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
    result = run_in_subprocess(f"from wsnloc.job_server import JobServer; JobServer([]).run({str(script)!r})")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert result.returncode == 0, result.stderr
    assert after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime >= 0.6


@forks
def test_when_the_server_dies_its_running_job_fails_naming_its_script_and_stops_and_the_next_starts_a_new_one(
        tmp_path, server):
    started, late = tmp_path / "started", tmp_path / "late"
    slow = write_script(tmp_path / "slow.py", f"""\
        import time
        open({str(started)!r}, "w").close()
        time.sleep(2)
        open({str(late)!r}, "w").close()
        """)
    errors = []
    thread = threading.Thread(target=lambda: errors.append(pytest.raises(JobFailed, server.run, slow)))
    thread.start()
    deadline = time.monotonic() + 20
    while not started.exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    first = server._client.process
    first.kill()
    thread.join(timeout=20)
    assert "slow.py: the job server exited with status -9 while it ran" in str(errors[0].value)
    time.sleep(2.5)
    assert not late.exists()                            # the job died with its server
    quick = write_script(tmp_path / "quick.py", "open(snakemake.output[0], 'w').write('ran')\n")
    server.run(quick, output=[str(tmp_path / "out")])
    assert (tmp_path / "out").read_text() == "ran" and server._client.process is not first


@forks
def test_a_server_whose_client_is_gone_still_waits_for_its_jobs_and_exits_cleanly(tmp_path):
    """Snakemake killed (SIGKILL) while a job runs: the job finishes as a `script:` job would,
    and the server exits 0 without a traceback."""
    done = tmp_path / "done"
    script = write_script(tmp_path / "job.py", f"import time\ntime.sleep(1)\nopen({str(done)!r}, 'w').close()\n")
    code = f"""\
        import os, signal, sys, threading, time
        from wsnloc.job_server import JobServer
        jobs = JobServer([])
        threading.Thread(target=jobs.run, args=({str(script)!r},), daemon=True).start()
        time.sleep(0.3)
        print(jobs._client.process.pid, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)
        """
    client = subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    server_pid = int(client.stdout.readline())
    client.wait(timeout=30)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and os.path.exists(f"/proc/{server_pid}"):
        time.sleep(0.05)
    assert done.exists() and not os.path.exists(f"/proc/{server_pid}")
    assert "Traceback" not in client.stderr.read()


def test_a_fresh_interpreter_runs_a_job_without_the_server(tmp_path, server):
    """Off Linux, in a process that runs one job, or with more than one thread."""
    out = tmp_path / "out.txt"
    script = write_script(tmp_path / "job.py", """\
        import os
        open(snakemake.output[0], "w").write(f"{snakemake.params['text']} {os.environ['OMP_NUM_THREADS']}")
        """)
    server.run(script, fork=False, output=[str(out)], params={"text": "fresh"})
    assert out.read_text() == "fresh 1"
    server.run(script, threads=3, output=[str(out)], params={"text": "threads"})
    assert out.read_text() == "threads 3" and server._client is None
    broken = write_script(tmp_path / "broken.py", "raise RuntimeError('boom')\n")
    with pytest.raises(JobFailed, match="broken.py exited with status 1"):
        server.run(broken, fork=False)
