"""Shared fixtures: lcm-gen's generated Python for our schemas, and real Drake traffic."""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import sysconfig
import time
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

from bridge.lcmcodec import SCHEMA_DIR
from bridge.transports.lcm import LcmEvent, read_log

SCRIPTS = Path(sysconfig.get_paths()["purelib"]) / "bin"  # the lcm wheel's real binaries


def lcm_url() -> str:
    """A multicast URL of this test process's own (ttl=0 keeps it on this host)."""
    return f"udpm://239.255.76.67:{7700 + os.getpid() % 200}?ttl=0"


@pytest.fixture(scope="session")
def lcmgen(tmp_path_factory: pytest.TempPathFactory) -> dict[str, type]:
    """lcm-gen's own generated Python classes for every schema in lcmtypes/, by full name."""
    out = tmp_path_factory.mktemp("lcmgen")
    schemas = sorted(str(path) for path in SCHEMA_DIR.glob("*.lcm"))
    subprocess.run([str(SCRIPTS / "lcm-gen"), "--python", "--ppath", str(out), *schemas], check=True)
    sys.path.insert(0, str(out))
    classes: dict[str, type] = {}
    try:
        for package in ("drake", "robotlocomotion"):
            for path in (out / package).glob("*.py"):
                if path.stem == "__init__":
                    continue
                # Load by file so that Drake's installed `drake` package does not shadow ours.
                spec = importlib.util.spec_from_file_location(f"lcmgen_{package}.{path.stem}", path)
                assert spec and spec.loader
                module: ModuleType = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(module)
                classes[f"{package}.{path.stem}"] = getattr(module, path.stem)
    finally:
        sys.path.remove(str(out))
    return classes


DRAKE_SCENE_SCRIPT = Path(__file__).parent / "drake_scene.py"


@pytest.fixture(scope="session")
def drake_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An LCM log recorded by the real lcm-logger while a pydrake simulation runs DrakeVisualizer."""
    folder = tmp_path_factory.mktemp("drake")
    log = folder / "drake.lcmlog"
    url = lcm_url()
    logger = subprocess.Popen(
        [str(SCRIPTS / "lcm-logger"), "--lcm-url", url, "-f", str(log)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 10
        while not log.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.3)
        subprocess.run([sys.executable, str(DRAKE_SCENE_SCRIPT), url, str(folder)], check=True, timeout=300)
        time.sleep(0.5)
    finally:
        logger.send_signal(signal.SIGINT)
        logger.wait(timeout=10)
    return log


@pytest.fixture(scope="session")
def drake_events(drake_log: Path) -> list[LcmEvent]:
    """Drake's viewer traffic from the log (DrakeLcm's own LCM_SELF_TEST left out)."""
    return list(read_log(drake_log, "DRAKE_.*"))


@pytest.fixture(scope="session")
def drake_mesh_dir(drake_log: Path) -> Iterator[Path]:
    yield drake_log.parent
