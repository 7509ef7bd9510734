"""Usage: python docs/scripts/small_twin_refine.py CACHE K  (the --cache of the small
full-campaign validation, in which twin K's calls are already cached; K as in --shard K/14).

Reruns the in-catalogue diagnosis of twin K of `validate("small", simulator="engine",
campaign="full", twin_repeats=3)` (twin seed 0, the preset's top-up of 3 seeds) with one
refinement round: `twin_refine_rounds.py CACHE K small 0 3 1`, which prints the verdict,
reason, ranking, best models, the refined effects' nodes, the held-out shrink and the rerun
checks. The refinement and the reruns are new engine calls (about an hour on one core at
small). Earlier versions of this script also replayed the twin with its effect removed,
at `refine=0`.
"""
import sys

from twin_refine_rounds import main

if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), "small", 0, 3, 1)
