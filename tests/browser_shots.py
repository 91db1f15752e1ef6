"""Screenshots of HTML replays with Debian's headless chromium (for the tests
that check what a person would see)."""

import os
import shutil
import signal
import subprocess

import matplotlib.image

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def Screenshot(html, png, user_data_dir):
    """The page ``html`` rendered at 800×600, as an RGB array."""
    # Headless chromium now and then hangs on this loaded machine (about one
    # screenshot in five, whatever the page): up to three attempts. A hung
    # chromium's children can outlive a kill of the browser process alone
    # and hold its profile (the likely reason three attempts once all hung),
    # so each attempt runs in its own process group, killed whole, with a
    # profile of its own.
    for attempt in range(3):
        try:
            _Run(_Command(html, png, f"{user_data_dir}-{attempt}"), timeout=60)
            break
        except subprocess.TimeoutExpired:
            if attempt == 2:
                raise
    return matplotlib.image.imread(str(png))[..., :3]


def _Command(html, png, user_data_dir):
    return [
        CHROMIUM,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={user_data_dir}",
        "--window-size=800,600",
        "--virtual-time-budget=8000",
        f"--screenshot={png}",
        f"file://{html}",
    ]


def _Run(command, timeout):
    """Runs ``command``; on timeout kills its whole process group and raises
    subprocess.TimeoutExpired; a non-zero exit raises CalledProcessError."""
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    try:
        out, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        raise
    if process.returncode:
        raise subprocess.CalledProcessError(process.returncode, command, out, err)
