"""Run the workflow's jobs in children forked from one pre-loaded Python process.

A Snakemake `script:` job starts a new interpreter, which imports numpy, pandas, pyarrow and
wsnloc (and matplotlib in the figure jobs) again before it does any work: 0.5-1.2 s of CPU per
job, about a seventh of the default build. Instead, each rule's `run:` block calls
`run_script(...)`. The job server (`python -m wsnloc.job_server STATEMENT ...`, started once
per Snakemake process) runs the import statements of the workflow's scripts while it waits
for requests; each job is then a child forked from it (copy-on-write: what the server has
imported costs the child nothing), which runs the rule's script as `__main__` with the
`snakemake` object the script expects (input, output, params, wildcards, log), and exits.
The Snakemake process itself never forks (it runs threads); the server is single-threaded,
so a fork copies no lock that another thread holds.

`run:` blocks run inside the Snakemake process only with `--force-use-threads`, which
`profiles/default/config.yaml` (Snakemake's workflow profile) sets; without it Snakemake
starts a whole Snakemake process for every `run:` job: slower, the same results.

Off Linux (no fork, or fork unsafe with the system's libraries, as on macOS, where Python's
multiprocessing does not fork either) every job runs in a fresh interpreter instead:
`python -m wsnloc.job_server --run SCRIPT`, the `snakemake` object pickled on its stdin.

Protocol of the server, on its stdin and stdout: a request is a 4-byte big-endian length
and a pickle of (job id, script path, namespace); a reply is the line "job_id exit_code"
when the job's child has ended (os.waitstatus_to_exitcode: negative for a signal). The
children's stdout goes to the server's stderr (their tracebacks too). The server ends when
its stdin closes, after its children; the client closes it and reaps the server at exit, so
that the jobs' CPU time counts in Snakemake's (as `time snakemake` and benchmarks/run.py
measure it).
"""

from __future__ import annotations

import ast
import atexit
import gc
import os
import pickle
import runpy
import select
import signal
import struct
import subprocess
import sys
import threading
import traceback
from concurrent.futures import Future
from pathlib import Path
from types import SimpleNamespace

HEADER = struct.Struct("!I")   # length of a request's pickle, in bytes
FORKS = sys.platform.startswith("linux")


class JobFailed(RuntimeError):
    """A job's script raised or exited with a non-zero status (its traceback is printed above)."""


def script_imports(scripts) -> list[str]:
    """The module-level import statements of the workflow's scripts, each once, in order of
    first appearance (e.g. "from wsnloc.report import figures"): what the server runs once,
    for all jobs."""
    statements: dict[str, None] = {}
    for script in scripts:
        for node in ast.parse(Path(script).read_text()).body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                statements[ast.unparse(node)] = None
    return list(statements)


# ---- client: in the Snakemake process -------------------------------------------------

_lock = threading.Lock()
_server: _Client | None = None


def start_server(preload: list[str]) -> None:
    """Start this process's job server (if it is not running and the platform forks), so that
    it runs the `preload` import statements before the first job arrives."""
    global _server
    with _lock:
        if FORKS and (_server is None or _server.process.poll() is not None):
            _server = _Client(preload)


def run_script(script: str | Path, preload: list[str], **namespace) -> None:
    """Run one job: `script` with a `snakemake` object holding `namespace` (input, output,
    params, wildcards, log), in a child of the job server (started with `preload` if needed)
    or, off Linux, in a fresh interpreter. Raises JobFailed naming the script and its log
    when the job fails."""
    script, job = Path(script).resolve(), SimpleNamespace(**namespace)
    if FORKS:
        start_server(preload)
        code = _server.run(script, job)
    else:
        code = subprocess.run([sys.executable, "-m", "wsnloc.job_server", "--run", str(script)],
                              input=pickle.dumps(job)).returncode
    if code != 0:
        how = f"was killed by signal {-code}" if code < 0 else f"exited with status {code}"
        logs = ", ".join(map(str, namespace.get("log", [])))
        raise JobFailed(f"{script.name} {how} (its error, if any, is printed above" + (f"; log: {logs})" if logs else ")"))


class _Client:
    """The Snakemake side of the server: sends requests, resolves each job's Future when its
    reply arrives (a reader thread), closes and reaps the server at exit."""

    def __init__(self, preload: list[str]):
        self.process = subprocess.Popen([sys.executable, "-m", "wsnloc.job_server", *preload],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        self.pending: dict[int, Future] = {}
        self.next_id = 0
        self.send_lock = threading.Lock()
        threading.Thread(target=self._replies, name="wsnloc-job-server", daemon=True).start()
        atexit.register(self.close)

    def run(self, script: Path, job: SimpleNamespace) -> int:
        """Exit code of the job's child (blocks the calling thread until the child ends)."""
        done: Future = Future()
        with self.send_lock:
            job_id, self.next_id = self.next_id, self.next_id + 1
            request = pickle.dumps((job_id, str(script), job))
            self.pending[job_id] = done
            try:
                self.process.stdin.write(HEADER.pack(len(request)) + request)
                self.process.stdin.flush()
            except (BrokenPipeError, ValueError):
                self.pending.pop(job_id, None)
                raise JobFailed(f"the job server has exited (status {self.process.poll()}); "
                                f"{script.name} was not run") from None
        return done.result()

    def _replies(self) -> None:
        for line in self.process.stdout:
            job_id, code = map(int, line.split())
            self.pending.pop(job_id).set_result(code)
        status = self.process.wait()
        with self.send_lock:
            for job_id in list(self.pending):    # the server died with jobs running
                self.pending.pop(job_id).set_exception(JobFailed(f"the job server exited with status {status}"))

    def close(self) -> None:
        try:
            self.process.stdin.close()
        except BrokenPipeError:
            pass
        self.process.wait()


# ---- server: python -m wsnloc.job_server STATEMENT ... --------------------------------

def serve(requests: int, replies: int, preload: list[str]) -> None:
    """Fork a child per request read from fd `requests` and write each child's exit code to fd
    `replies` when it ends; return when `requests` is closed and every child has ended.

    While no request waits, run the next of the `preload` import statements (a child forked
    later finds those modules loaded; one forked earlier imports what it needs itself), each
    followed by gc.freeze (the loaded objects leave the collector's generations, so that no
    child scans them again). A statement that fails is skipped: the job whose script runs it
    raises the same error, with its traceback."""
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_w, False)
    signal.set_wakeup_fd(wake_w)                   # a SIGCHLD ends the select below
    signal.signal(signal.SIGCHLD, lambda *_: None)
    children: dict[int, int] = {}                  # pid -> job id
    reader = os.fdopen(requests, "rb", buffering=0)
    pending, accepting = list(preload), True
    while accepting or children:
        ready, _, _ = select.select([requests, wake_r] if accepting else [wake_r], [], [], 0 if pending else None)
        if not ready and pending:
            _preload(pending.pop(0))
            continue
        if wake_r in ready:
            os.read(wake_r, 4096)
        if requests in ready:
            header = _read_exactly(reader, HEADER.size)
            body = header and _read_exactly(reader, HEADER.unpack(header)[0])
            if body is None:
                accepting = False
            else:
                job_id, script, job = pickle.loads(body)
                pid = os.fork()
                if pid == 0:
                    for fd in (wake_r, wake_w, requests, replies):
                        os.close(fd)
                    _child(script, job)            # never returns
                children[pid] = job_id
        while children:
            pid, status = os.waitpid(-1, os.WNOHANG)
            if pid == 0:
                break
            os.write(replies, f"{children.pop(pid)} {os.waitstatus_to_exitcode(status)}\n".encode())


def _preload(statement: str) -> None:
    try:
        exec(statement, {})
    except Exception:   # noqa: BLE001  (see serve)
        pass
    gc.freeze()


def _read_exactly(reader, size: int) -> bytes | None:
    """`size` bytes of the request stream; None at its end (the client closed it)."""
    data = b""
    while len(data) < size:
        chunk = reader.read(size - len(data))
        if not chunk:
            return None
        data += chunk
    return data


def _child(script: str, job: SimpleNamespace) -> None:
    """A job in a forked child: signals as in a fresh interpreter, then _run."""
    signal.set_wakeup_fd(-1)
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.default_int_handler)    # Ctrl-C stops a job as before
    _run(script, job)


def _run(script: str, job: SimpleNamespace) -> None:
    """The script run as __main__ with `snakemake` = job; exit status 0, the script's
    SystemExit code, or 1 after printing its traceback. The process ends with os._exit after
    flushing the log handlers and the standard streams: no interpreter teardown, which frees
    every loaded module's objects one by one (measured 0.1 s of CPU with pandas loaded, 0.25 s
    with matplotlib as well)."""
    code = 0
    try:
        runpy.run_path(script, init_globals={"snakemake": job}, run_name="__main__")
    except SystemExit as stop:
        code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
    except BaseException:   # noqa: BLE001  (any failure is the job's: printed, then status 1)
        traceback.print_exc()
        code = 1
    if "logging" in sys.modules:
        sys.modules["logging"].shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def main(argv: list[str]) -> None:
    """`--run SCRIPT`: one job in this fresh interpreter (its `snakemake` object pickled on
    stdin). Otherwise the server: protocol on its own copies of stdin and stdout, the jobs'
    output to stderr, Ctrl-C left to the jobs (the server ends when its stdin closes)."""
    if argv[:1] == ["--run"]:
        _run(argv[1], pickle.load(sys.stdin.buffer))
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    requests, replies = os.dup(0), os.dup(1)
    os.dup2(2, 1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    serve(requests, replies, argv)


if __name__ == "__main__":
    main(sys.argv[1:])
