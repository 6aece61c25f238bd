"""Run the workflow's jobs in children forked from one pre-loaded Python process.

A Snakemake `script:` job starts a new interpreter, which imports numpy, pandas, pyarrow and
wsnloc (and matplotlib in the figure jobs) again before it does any work: 0.5-1.3 s of CPU per
job, about a seventh of the default build. Instead, each rule's `run:` block calls
`JobServer.run(...)`. At the first job, the JobServer of the Snakemake process starts the
server (`python -m wsnloc.job_server STATEMENT ...`), which runs the import statements of
the workflow's scripts while it waits for requests; each job is a child forked from it
(copy-on-write: what the server has imported costs the child nothing), which runs the rule's
script as `__main__` with the `snakemake` object the script expects (input, output, params,
wildcards, log, threads, resources) and exits.

Fork safety: the Snakemake process never forks (it runs threads); the server runs one Python
thread. Its native threads are jemalloc's background thread (pyarrow's allocator) and none of
OpenBLAS's (the server runs, as Snakemake runs a one-thread `script:` job, with
OPENBLAS_NUM_THREADS=1 and the like); jemalloc, OpenBLAS and Arrow take and release their
locks around a fork (pthread_atfork), as multiprocessing's fork start method relies on.

`run:` blocks run inside the Snakemake process only with `--force-use-threads`, which
`profiles/default/config.yaml` (Snakemake's workflow profile) sets; without it Snakemake
starts a Snakemake process for every `run:` job, which then runs its job in a fresh
interpreter (`fork=False`): slower than a `script:` job, the same results. Jobs also run in a
fresh interpreter (`python -m wsnloc.job_server --run SCRIPT`, the `snakemake` object pickled
on stdin) off Linux (no fork, or a fork unsafe with the system's libraries, as on macOS, where
multiprocessing does not fork either) and when a rule asks for more than one thread.

Protocol of the server, on its stdin and stdout: a request is an 8-byte header (length of
the body, job id; big-endian) and the body, a pickle of (script path, snakemake object),
unpickled in the job's child (a namespace that does not unpickle fails its job only); a reply
is the line "job_id exit_code" when the job's child has ended (os.waitstatus_to_exitcode:
negative for a signal). The children's stdout goes to the server's stderr, with their
tracebacks. The server ends when its stdin closes, after its children; the client closes it
and reaps the server at exit, so that the jobs' CPU time counts in Snakemake's (as `time
snakemake` and benchmarks/run.py measure it). A child dies with the server (PR_SET_PDEATHSIG):
no job writes its outputs after Snakemake has counted it as failed.
"""

from __future__ import annotations

import ast
import atexit
import ctypes
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
import warnings
from concurrent.futures import Future
from pathlib import Path
from types import SimpleNamespace

HEADER = struct.Struct("!II")    # body length in bytes, job id
FORKS = sys.platform.startswith("linux")
# What Snakemake's shell sets to a job's thread count for a `script:` job (snakemake/shell.py).
THREAD_VARIABLES = ("OMP_NUM_THREADS", "GOTO_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
PR_SET_PDEATHSIG = 1             # linux/prctl.h


class JobFailed(RuntimeError):
    """A job's script raised or exited with a non-zero status, or the job server died."""


def script_imports(scripts) -> list[str]:
    """The module-level import statements of the workflow's scripts, each once, in order of
    first appearance (e.g. "from wsnloc.report import figures"): what the server runs once,
    for all jobs. A script that does not parse adds none (its job reports the SyntaxError)."""
    statements: dict[str, None] = {}
    for script in scripts:
        try:
            body = ast.parse(Path(script).read_text()).body
        except SyntaxError:
            continue
        statements.update(dict.fromkeys(ast.unparse(node) for node in body
                                        if isinstance(node, (ast.Import, ast.ImportFrom))))
    return list(statements)


def thread_environment(threads: int) -> dict[str, str]:
    """This process's environment with THREAD_VARIABLES set to `threads`."""
    return {**os.environ, **dict.fromkeys(THREAD_VARIABLES, str(threads))}


# ---- client: in the Snakemake process -------------------------------------------------

class JobServer:
    """The job server of one process (a Snakemake run), started at its first forked job and
    started again if it has died; `preload`: the import statements it runs while idle."""

    def __init__(self, preload: list[str]):
        self.preload = list(preload)
        self._client: _Client | None = None
        self._lock = threading.Lock()

    def run(self, script: str | Path, fork: bool = True, threads: int = 1, **namespace) -> None:
        """Run one job: `script` with a `snakemake` object holding `namespace` (input, output,
        params, wildcards, log, resources) and `threads`, in a child of the server (fork, on
        Linux, one thread) or in a fresh interpreter. Raises JobFailed naming the script and
        its log when the job fails."""
        script, job = Path(script).resolve(), SimpleNamespace(threads=threads, **namespace)
        if fork and FORKS and threads == 1:
            code = self.client().run(script, job)
        else:
            code = subprocess.run([sys.executable, "-m", "wsnloc.job_server", "--run", str(script)],
                                  input=pickle.dumps(job), env=thread_environment(threads)).returncode
        if code != 0:
            how = f"was killed by signal {-code}" if code < 0 else f"exited with status {code}"
            logs = ", ".join(map(str, namespace.get("log", [])))
            raise JobFailed(f"{script.name} {how} (its error, if any, is printed above"
                            + (f"; log: {logs})" if logs else ")"))

    def client(self) -> _Client:
        """The running server's client (started now if there is none or it has died)."""
        with self._lock:
            if self._client is None or self._client.process.poll() is not None:
                self._client = _Client(self.preload)
            return self._client


class _Client:
    """The Snakemake side of a server: sends requests, resolves each job's Future when its
    reply arrives (a reader thread; if the server dies, every waiting job fails naming its
    script), closes and reaps the server at exit."""

    def __init__(self, preload: list[str]):
        self.process = subprocess.Popen([sys.executable, "-m", "wsnloc.job_server", *preload],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=thread_environment(1))
        self.pending: dict[int, tuple[str, Future]] = {}    # job id -> (script name, its exit code)
        self.next_id = 0
        self.lock = threading.Lock()
        threading.Thread(target=self._replies, name="wsnloc-job-server", daemon=True).start()
        atexit.register(self.close)

    def run(self, script: Path, job: SimpleNamespace) -> int:
        """Exit code of the job's child (blocks the calling thread until the child ends)."""
        body, done = pickle.dumps((str(script), job)), Future()
        with self.lock:
            job_id, self.next_id = self.next_id, self.next_id + 1
            self.pending[job_id] = (script.name, done)
            try:
                self.process.stdin.write(HEADER.pack(len(body), job_id) + body)
                self.process.stdin.flush()
            except (BrokenPipeError, ValueError):    # the server has exited, or stdin is closed
                self.pending.pop(job_id)
                raise JobFailed(f"the job server has exited (status {self.process.poll()}); "
                                f"{script.name} was not run") from None
        return done.result()

    def _replies(self) -> None:
        try:
            for line in self.process.stdout:
                job_id, code = map(int, line.split())
                with self.lock:
                    _, done = self.pending.pop(job_id)
                done.set_result(code)
        except BaseException:
            self.process.kill()         # a reply that does not parse: no later reply can be trusted
            raise
        finally:
            status = self.process.wait()
            with self.lock:
                failed, self.pending = self.pending, {}
            for name, done in failed.values():
                done.set_exception(JobFailed(f"{name}: the job server exited with status {status} while it ran"))

    def close(self) -> None:
        try:
            self.process.stdin.close()
        except BrokenPipeError:
            pass
        self.process.wait()


# ---- server: python -m wsnloc.job_server STATEMENT ... --------------------------------

def serve(requests: int, replies: int, preload: list[str]) -> None:
    """Fork a child per request read from fd `requests` and write each child's exit code to fd
    `replies` when it ends; return when `requests` is closed and every child has ended (a
    closed `replies`: the client is gone; the children are still waited for).

    While no request waits, and until `requests` closes, run the next of the `preload` import
    statements (_preload): a child forked later finds those modules loaded; one forked earlier
    imports what it needs itself."""
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_w, False)
    signal.set_wakeup_fd(wake_w)                   # a SIGCHLD ends the select below
    signal.signal(signal.SIGCHLD, lambda *_: None)
    interrupt = signal.getsignal(signal.SIGINT)    # what the jobs get: the server's own, as started
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the jobs'; the server ends with its stdin
    children: dict[int, int] = {}                  # pid -> job id
    reader = os.fdopen(requests, "rb", buffering=0)
    to_preload, accepting, answering = list(preload), True, True
    while accepting or children:
        preloading = accepting and to_preload
        ready, _, _ = select.select([requests, wake_r] if accepting else [wake_r], [], [], 0 if preloading else None)
        if not ready and preloading:
            _preload(to_preload.pop(0))
            continue
        if wake_r in ready:
            os.read(wake_r, 4096)
        if requests in ready:
            header = _read_exactly(reader, HEADER.size)
            length, job_id = HEADER.unpack(header) if header else (0, 0)
            body = header and _read_exactly(reader, length)
            if body is None:
                accepting = False
            else:
                try:
                    pid = os.fork()
                except OSError as error:
                    print(f"wsnloc job server: cannot start job {job_id}: {error}", file=sys.stderr)
                    answering = _reply(replies, job_id, 1) and answering
                    continue
                if pid == 0:
                    _child(body, interrupt, closing=(wake_r, wake_w, requests, replies))   # never returns
                children[pid] = job_id
        while children:
            pid, status = os.waitpid(-1, os.WNOHANG)
            if pid == 0:
                break
            job_id = children.pop(pid, None)           # None: a process a preloaded module started
            if job_id is not None and answering:
                answering = _reply(replies, job_id, os.waitstatus_to_exitcode(status))


def _reply(replies: int, job_id: int, code: int) -> bool:
    """Write a job's exit code to the client; False when the client is gone."""
    try:
        os.write(replies, f"{job_id} {code}\n".encode())
        return True
    except BrokenPipeError:
        return False


def _preload(statement: str) -> None:
    """Run one import statement in the server, then gc.freeze: the loaded objects leave the
    collector's generations, so that no child scans them again. A statement that fails is
    skipped: the job whose script runs it raises the same error, with its traceback."""
    try:
        exec(statement, {})
    except Exception:   # noqa: BLE001  (see the docstring)
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


def _child(body: bytes, interrupt, closing: tuple[int, ...]) -> None:
    """A job in a forked child: signals as in a fresh interpreter (SIGINT as the server was
    started with), dies with the server, then runs the pickled (script, snakemake object)."""
    server = os.getppid()
    signal.set_wakeup_fd(-1)
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)
    signal.signal(signal.SIGINT, interrupt)
    for fd in closing:
        os.close(fd)
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != server:                   # the server died before prctl took effect
        os._exit(1)
    try:
        script, job = pickle.loads(body)
    except BaseException:   # noqa: BLE001  (this job's failure: printed, then status 1)
        traceback.print_exc()
        os._exit(1)
    _run(script, job)


def _run(script: str, job: SimpleNamespace) -> None:
    """The script run as __main__ with `snakemake` = job (sys.argv [script], its folder first
    on sys.path, as `python script` has them); exit status 0, the script's SystemExit code
    (a message: printed, then 1, as Python does), or 1 after printing its traceback. The
    process ends with os._exit after flushing the log handlers and the standard streams: no
    interpreter teardown, which frees every loaded module's objects one by one (measured 0.1 s
    of CPU with pandas loaded, 0.25 s with matplotlib as well)."""
    sys.argv = [script]
    sys.path.insert(0, os.path.dirname(script))
    code = 0
    try:
        runpy.run_path(script, init_globals={"snakemake": job}, run_name="__main__")
    except SystemExit as stop:
        if stop.code is None or isinstance(stop.code, int):
            code = stop.code or 0
        else:
            print(stop.code, file=sys.stderr)
            code = 1
    except BaseException:   # noqa: BLE001  (any failure is the job's: printed, then status 1)
        traceback.print_exc()
        code = 1
    if "logging" in sys.modules:
        sys.modules["logging"].shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def main(argv: list[str]) -> None:
    """`--run SCRIPT`: one job in this fresh interpreter, its `snakemake` object pickled on
    stdin. Otherwise the server of the import statements `argv`: protocol on its own copies
    of stdin and stdout, the jobs' output to stderr in both cases."""
    stdin, stdout = os.dup(0), os.dup(1)
    os.dup2(2, 1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    if argv[:1] == ["--run"]:
        with os.fdopen(stdin, "rb") as request:
            job = pickle.load(request)
        _run(argv[1], job)
    else:
        # Python >= 3.12 warns at each fork of a process with more than one thread: here the
        # jemalloc thread, which forks safely (see the module docstring).
        warnings.filterwarnings("ignore", message=r".*use of fork\(\) may lead to deadlocks", category=DeprecationWarning)
        serve(stdin, stdout, argv)


if __name__ == "__main__":
    main(sys.argv[1:])
