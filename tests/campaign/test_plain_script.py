"""``forcecal.calibrate`` from a plain script, one without ``if __name__ == "__main__":``.

A ``spawn`` worker process imports the main module again: a plain script would run its top
level once more in every worker, and the pool would break (``BrokenProcessPool``). The API is
serial by default, so a plain script completes; asking it for workers is refused with one clear
InputError naming the script's line, before any worker starts. Each script runs in its own
interpreter (a subprocess), as a user runs it.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

TIMEOUT_S = 300


def _run(folder: Path, name: str, code: str, *argv: str) -> subprocess.CompletedProcess:
    """The script ``code`` written as ``folder/name`` and run there with ``argv``."""
    script = folder / name
    script.write_text(textwrap.dedent(code), encoding="utf-8")
    return subprocess.run([sys.executable, str(script), *argv], cwd=folder, capture_output=True,
                          text=True, timeout=TIMEOUT_S, check=False)


CALIBRATE = """\
    import sys
    import forcecal

    print("started", flush=True)
    rig = forcecal.load_rig(sys.argv[1] + "/rig.toml")
    scan = forcecal.read_scan(sys.argv[1] + "/scan.uff", rig=rig)
    result = forcecal.calibrate(rig, scan, sys.argv[1] + "/manifest_small.csv"{workers})
    print("law", result.calibration.law, flush=True)
    result.calibration.save("calibration.json")
"""


def test_a_plain_script_calibrates_with_the_defaults(campaign_dir, tmp_path):
    done = _run(tmp_path, "plain.py", CALIBRATE.format(workers=""), str(campaign_dir))
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["started", "law k_i2_sfe2"]   # run once: no worker
    assert "Traceback" not in done.stderr
    assert (tmp_path / "calibration.json").is_file()


def test_workers_asked_in_a_plain_script_are_refused_clearly(campaign_dir, tmp_path):
    code = CALIBRATE.format(workers=", workers=2").replace(
        "    result = forcecal.calibrate(", "    try:\n        result = forcecal.calibrate(")
    code = code.replace("    print(\"law\"", "    except forcecal.errors.ForcecalError as exc:\n"
                        "        print(type(exc).__name__, exc)\n        raise SystemExit(3)\n"
                        "    print(\"law\"")
    done = _run(tmp_path, "plain_workers.py", code, str(campaign_dir))
    assert done.returncode == 3, done.stderr
    started, refusal = done.stdout.splitlines()
    assert started == "started"                        # no worker ran the script again
    assert refusal.startswith("InputError workers = 2: "), refusal
    script = tmp_path / "plain_workers.py"
    for words in (f"script '{script}' line 8", "if __name__ == \"__main__\":", "workers=1"):
        assert words in refusal, refusal
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plain_workers.py"]


# --------------------------------------------------------------------------------------------
# which scripts a worker would run again


WHERE = "from forcecal.cluster.pool import unguarded_script\n"


@pytest.mark.parametrize(("code", "expected"), [
    (WHERE + "print(unguarded_script())\n", "line 2"),
    (WHERE + "def main():\n    print(unguarded_script())\n\n\nmain()\n", "line 6"),
    (WHERE + "if __name__ == '__main__':\n    print(unguarded_script())\n", "None"),
    (WHERE + "def main():\n    print(unguarded_script())\n\n\nif \"__main__\" == __name__:\n"
             "    main()\n", "None"),
    (WHERE + "if __name__ == '__main__':\n    pass\nprint(unguarded_script())\n", "line 4"),
], ids=["top-level", "function-at-top-level", "guarded", "guarded-function", "after-the-guard"])
def test_unguarded_calls_are_found_in_a_script(tmp_path, code, expected):
    done = _run(tmp_path, "script.py", code)
    assert done.returncode == 0, done.stderr
    out = done.stdout.strip()
    if expected == "None":
        assert out == "None"
    else:
        assert out == f"script '{tmp_path / 'script.py'}' {expected}"


def test_interactive_and_package_mains_are_not_run_again(tmp_path):
    done = subprocess.run([sys.executable, "-c", WHERE + "print(unguarded_script())"],
                          capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    assert done.stdout.strip() == "None", done.stderr
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "__init__.py").write_text("", encoding="utf-8")
    (package / "__main__.py").write_text(WHERE + "print(unguarded_script())\n", encoding="utf-8")
    (package / "mod.py").write_text(WHERE + "print(unguarded_script())\n", encoding="utf-8")
    run = [sys.executable, "-m"]
    as_package = subprocess.run([*run, "pkg"], cwd=tmp_path, capture_output=True, text=True,
                                timeout=TIMEOUT_S, check=False)
    assert as_package.stdout.strip() == "None", as_package.stderr
    as_module = subprocess.run([*run, "pkg.mod"], cwd=tmp_path, capture_output=True, text=True,
                               timeout=TIMEOUT_S, check=False)
    assert as_module.stdout.strip() == f"script '{package / 'mod.py'}' line 2", as_module.stderr


def test_the_api_is_serial_unless_asked(monkeypatch):
    from forcecal import api

    asked: list[int | None] = []
    monkeypatch.setattr(api, "build_spatial_model", lambda rig, scan: "model")
    monkeypatch.setattr(api, "calibrate_campaign", lambda *a, **kw: asked.append(kw["workers"]))
    api.calibrate("rig", "scan", "manifest.csv")
    api.calibrate("rig", "scan", "manifest.csv", workers=3)
    assert asked == [1, 3]
