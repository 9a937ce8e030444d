"""Hydra's submitit launchers (``hydra/launcher=submitit_slurm`` or ``submitit_local``, the ``cluster`` extra): a job
that ends without a result is one line in the sweep's command, not submitit's traceback.

The launcher waits for each job's result file; a job killed (SIGKILL, Slurm's pre-emption or time limit, out of
memory) or ended by laughlab's own error line (``sys.exit``) leaves none, and submitit's ``UncompletedJobError``
went through Hydra, which printed its traceback (and the job's) and exited 1 (a cluster review).  The sweep now
says which job, the line the job said if it said one, where its log is, and how far the sweep got; the finished
points are kept and the same command resumes the rest.
"""
from __future__ import annotations

import re
from pathlib import Path


class JobLost(BaseException):
    """A sweep's job ended without a result: its line.  A BaseException so that Hydra, which prints the
    traceback of any Exception a launcher raises, lets it through to laughlab's command line."""


def job_lost_line(message: str, progress: str) -> str:
    """The line for submitit's ``UncompletedJobError`` ``message``; ``progress``: how far the sweep got (e.g.
    ``2 of 4 points finished; run the same command again to resume``)."""
    said = re.findall(r"^laughlab: error: (.*)$", message, flags=re.M)
    result = re.search(r"with path (\S+)_result\.pkl", message)
    log = f"{result.group(1)}_log.err" if result else None
    job = re.search(r"^Job (\S+)", message)
    name = f"sweep job {job.group(1)}" if job else "a sweep job"
    if said:
        what = f"{name}: {said[-1]}"
    else:
        what = f"{name} ended without a result (killed, out of time or memory?)"
    where = f" (its log: {log})" if log and Path(log).exists() else ""
    return f"{what}{where}; {progress}"


def guard_submitit(progress) -> None:
    """Have Hydra's submitit launcher, if installed, raise :class:`JobLost` for a job without a result;
    ``progress()``: the sweep's progress words at that moment."""
    try:
        from hydra_plugins.hydra_submitit_launcher import submitit_launcher
        from submitit.core.utils import UncompletedJobError
    except ImportError:   # no cluster extra: no submitit launcher to guard
        return
    base = submitit_launcher.BaseSubmititLauncher
    launch = getattr(base.launch, "__wrapped__", base.launch)

    def guarded(self, *args, **kwargs):
        try:
            return launch(self, *args, **kwargs)
        except UncompletedJobError as exc:
            raise JobLost(job_lost_line(str(exc), progress())) from None

    guarded.__wrapped__ = launch
    base.launch = guarded
