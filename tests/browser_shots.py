"""Screenshots of HTML replays with Debian's headless chromium (for the tests
that check what a person would see)."""

import shutil
import subprocess

import matplotlib.image

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def Screenshot(html, png, user_data_dir):
    """The page ``html`` rendered at 800×600, as an RGB array."""
    command = [
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
    # Headless chromium now and then hangs on this loaded machine (about one
    # screenshot in five, whatever the page): up to three attempts.
    for attempt in range(3):
        try:
            subprocess.run(command, capture_output=True, timeout=60, check=True)
            break
        except subprocess.TimeoutExpired:
            if attempt == 2:
                raise
    return matplotlib.image.imread(str(png))[..., :3]
