"""What a process running the controller in real time does once it is set
up."""

import gc


def FreezeHeap() -> None:
    """Collects garbage once, then moves every object alive now into the
    collector's permanent generation (``gc.freeze``).

    After setup the heap holds hundreds of thousands of long-lived objects
    (pydrake, numba, the diagram). Python's full collections walk them all:
    measured in ``sm2ith bench`` (Ridgeback–UR10, 3 people, 200 steps), a
    few full collections of 15–100 ms each, one of which made a 35 ms
    control step take 135 ms. Frozen objects are never walked again; only
    what the run allocates afterwards is (the log's records, a few hundred
    objects per step). Nothing is freed that would have been: the frozen
    objects were alive. But cycles among them are never collected once
    they die, so this is for a process that runs one controller (the
    benchmark, ``sm2ith hardware``), not for a campaign worker that builds
    one simulation after another."""
    gc.collect()
    gc.freeze()
