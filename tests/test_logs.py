"""A failed run ends with what failed (freqbrdf.util.logs.failure_summary)."""

from freqbrdf.util.logs import failure_summary, first_error_line

SNAKEMAKE_LOG = """\
[Fri Nov 27 23:03:39 2026]
localrule render_capture:
    output: results/captures/sphere/museum/test
    log: results/logs/render_capture/sphere_museum_test.log
    wildcards: object=sphere, env=museum
RuleException:
CalledProcessError in file "workflow/rules/captures.smk", line 40:
[Fri Nov 27 23:03:40 2026]
Error in rule render_capture:
    message: None
    jobid: 7
    input: results/envs/museum.exr, results/objects/sphere/mesh.ply
    output: results/captures/sphere/museum/test
    log: results/logs/render_capture/sphere_museum_test.log (check log file(s) for error details)
    conda-env: /work/.snakemake/conda/abc
Error in rule fit_sh:
    jobid: 9
    output: results/sh/sphere/studio/gt
Exiting because a job execution failed. Look above for error messages
"""


def test_each_failed_job_is_named_with_its_log_and_the_first_error_line(tmp_path):
    log = tmp_path / "results/logs/render_capture/sphere_museum_test.log"
    log.parent.mkdir(parents=True)
    log.write_text("23:03:39 INFO [freqbrdf.render_capture] start render_capture\n"
                   "23:03:40 ERROR [freqbrdf.render_capture] render_capture failed: results/envs/museum.exr: "
                   "not a readable OpenEXR file\nTraceback (most recent call last):\nValueError: ...\n")
    assert failure_summary(SNAKEMAKE_LOG, tmp_path) == [
        "FreqBRDF: 2 job(s) failed:",
        "  rule render_capture (results/captures/sphere/museum/test): "
        "log results/logs/render_capture/sphere_museum_test.log",
        "    23:03:40 ERROR [freqbrdf.render_capture] render_capture failed: results/envs/museum.exr: "
        "not a readable OpenEXR file",
        "  rule fit_sh (results/sh/sphere/studio/gt): log none",
        "    the log says nothing; see the rule error above",
    ]
    assert failure_summary("Nothing to be done.\n", tmp_path) == []


def test_the_first_error_line_falls_back_to_the_exception_then_the_last_line():
    assert first_error_line("a\nTraceback (most recent call last):\n  x\nKeyError: 'views'\nb\n") == "KeyError: 'views'"
    assert first_error_line("a\n\nlast words\n\n") == "last words"
    assert first_error_line("") == ""


def test_a_job_dies_with_the_process_that_started_it(tmp_path):
    """A parent starts a job that calls die_with_parent and sleeps; the parent is SIGKILLed alone
    (as a killed Snakemake): the job must not live on as an orphan."""
    import os
    import subprocess
    import sys
    import time

    job = "import time; from freqbrdf.util.logs import die_with_parent; die_with_parent(); time.sleep(600)"
    parent = subprocess.Popen([sys.executable, "-c",
                               f"import subprocess, sys, time; p = subprocess.Popen([sys.executable, '-c', {job!r}]); "
                               "print(p.pid, flush=True); time.sleep(600)"], stdout=subprocess.PIPE, text=True)
    child = int(parent.stdout.readline())
    time.sleep(0.5)  # the job has made its request
    os.kill(child, 0)  # alive while its parent is
    parent.kill()
    parent.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        try:
            os.kill(child, 0)
        except ProcessLookupError:
            return
        time.sleep(0.05)
    os.kill(child, 9)
    raise AssertionError(f"job {child} outlived its killed parent")
