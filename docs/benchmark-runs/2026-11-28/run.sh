#!/bin/bash
# The benchmark of 2026-11-28: the late-night script of 2026-11-27, with
# the code at the start of the session (1fce1c4) as "before" and the code
# at the end as "after": three runs of 200 steps each with 3 people, both
# robots; 0 people three runs; 10 people one run.
#   BEFORE=<worktree of 1fce1c4> bash docs/benchmark-runs/2026-11-28/run.sh OUT
exec bash "$(dirname "$0")/../2026-11-27-late/run.sh" "$@"
