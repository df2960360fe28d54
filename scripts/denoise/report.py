#!/usr/bin/env python3
"""The denoising section of docs/RESULTS.md from scripts/bench-denoise.sh's rows.

    python3 report.py ROWS.csv --spp N --seeds N --reference-spp N

Per scene and method: the mean over seeds of RMSE and relMSE against the reference, RMSE as a
ratio of the unfiltered RMSE, and the filter's seconds; then, for each of lightsplit's filters,
whether it is at or below OIDN in both metrics on every scene. Prints the section, without its
markers: scripts/bench-denoise.sh writes it into docs/RESULTS.md through scripts/results-section.py.
"""

import argparse
import collections
import csv
import os
import sys

# What the measurements say, as text: checked against the tables above when they change.
FINDINGS = """**Where the remaining error is.** On the gallery, against OIDN (seed 1): our relMSE is
9.43e-4 against 7.61e-4. Split by pixel class, ours against OIDN's: the mixed pixels on object
borders (coverage below 1, 2352 pixels) 1.80e-4 against 1.23e-4; the pixels within 4 of a border
(6047) 1.73e-4 against 1.05e-4; the interior (57137) 5.91e-4 against 5.33e-4. About a third of
the gap in each. By object, the ceiling carries 4.6e-4 against 3.0e-4 and the back wall 2.2e-4
against 1.8e-4; the carpet, the pictures and the marble are better than OIDN's. The interior's
share is low-frequency blotches on the dark ceiling wider than the filter's reach (4 passes of
3x3 reach 15 pixels); more passes or a wider kernel do not help (indirect at 5 passes: gallery
relMSE 9.57e-4 with `sigma_l` 5, 9.83e-4 with 4), because the variance carried through the
passes tightens the colour stop as it goes. Near borders our window is one-sided (no tap
crosses an object ID, the paper's rule), so a gradient into a corner is averaged from one side
only. Mixed pixels: letting them gather from both of their objects (their normal stop at a
tenth; tried on an earlier setting) took the gallery from 9.95e-4 to 9.44e-4 and the Cornell box
from 2.56e-4 to 2.40e-4, but `paper-sky` from 6.7e-5 to 9.9e-5 (above OIDN's 9.6e-5), and was not
kept: a pixel half on the sky holds half an object's light, and
gathering full-coverage neighbours biases it. Telling those apart needs the share of a pixel's
samples that missed every object, which the film does not keep yet. The reference's own noise
is about 4.5e-4 of the gallery's relMSE (2.9e-2 at 64 independent samples, over 64): about half
of ours and 60% of OIDN's, so the true gap is larger than the table's (1.25x before issue 41's
check, 1.32x with it).

**Settings measured** (64 spp, seeds 1 and 2, `filter` of the same films; RMSE / relMSE):
- One colour stop for every component (`sigma_l=6`, 4 passes, `sigma_n=128`, `sigma_z=1`, the
  previous `--denoise`): paper-sky 3.73e-3 / 7.19e-5, gallery 4.91e-3 / 1.07e-3, cornell
  6.46e-3 / 2.65e-4. Each component its own: the direct light at `sigma_l` 1.5, the rest
  unchanged, 3.40e-3 / 6.27e-5, 4.59e-3 / 1.03e-3, 6.44e-3 / 2.60e-4 (sobol leaves the direct
  light nearly clean: a tight stop keeps it sharp). One pass for it is as good as four (3.37e-3
  / 6.18e-5, 4.57e-3 / 1.02e-3, 6.44e-3 / 2.59e-4) at a quarter of its time; none at all is
  worse on the Cornell box's soft shadows (relMSE 2.51e-4 against 2.48e-4 with the final
  setting). The caustics' stop loosened from 12 to 24: gallery 4.54e-3 / 9.95e-4 to 4.53e-3
  / 9.91e-4, a small gain (the other scenes have no caustics).
- Then the shared stops: `sigma_n` 32 and `sigma_z` 2 (from 128 and 1), and the indirect light
  at `sigma_l` 6: 3.35e-3 / 6.39e-5, 4.39e-3 / 9.34e-4, 6.41e-3 / 2.48e-4, the `--denoise` of
  the table. `sigma_z` 0.5 is worse everywhere (gallery relMSE 1.20e-3); `sigma_l` 4 or 10 on
  indirect worse on the gallery (9.90e-4, 9.60e-4).
- `components` against `indirect` with the same stops: gallery 4.39e-3 / 9.34e-4 against 7.04e-3
  / 3.51e-3 (its noise is also in the caustics and the spotlights' direct light).
- 3x3 taps against 5x5: within 5% in error (5x5: paper-sky relMSE 5% worse, gallery 2% better) at
  half the time, so `--denoise` uses 3x3, 4 passes.

**Time.** `cargo bench --bench filter` (criterion, warm, on its synthetic film: direct light
nearly clean, indirect noise everywhere, no caustics) on this 2-core machine:

| | 256x256 | 3840x2160 | budget |
|---|---|---|---|
| `--denoise` (3x3, 4 passes, components), checked against the halves (`cross=1`, issue 41) | 31.3 ms (72.9 before the steps below) | 4.09 s (9.23 before) | 10 ms, 1.5 s: **missed**, 3.1x and 2.7x |
| the same unchecked (`cross=0`; before issue 41, `--denoise`) | 13.5 ms (15.6 before issue 41) | 2.53 s (1.93 before) | **missed**, 1.35x and 1.7x |
| the same on indirect alone | 9.4 ms | 1.28 s | met |
| `atrous` defaults (5x5, 5 passes), indirect | 23.4 ms | 2.84 s | |
| `atrous` defaults, components | 40.0 ms | 4.83 s | |

On the real films (`filter --json`, a fresh process, first-touch page faults included) the
gallery, with its caustics a third live layer, took 22 to 33 ms over the runs made. Where the time goes (`perf record`, the gallery's film, 200 runs
of `--denoise`): the tap loop 39%, the geometric weights 6%, the colour stops (the 3x3 variance
blur) 10%, page faults of the fresh buffers 5%, and the rest (demodulation, the guides, the ends
of rows, the multiply-back, scheduling) about 40%. It is not the vector width: the same code built for AVX2 (`-C
target-cpu=native`) is only 6 to 11% faster (paper-sky 14.3 to 13.2 ms, gallery 23.4 to 21.2
ms, medians of 100 runs, three rounds alternated), and two threads run 1.9x faster than one. The tap loop
streams 21 arrays per tap (the centre's and the tap's guides and planes, and five sums read and
written); the next step is to hold a block of centres and their sums in registers across all
taps of a pass, which cuts that to the tap's 10. Using the single-layer fused loop when only
one layer of a row is live gave nothing (paper-sky medians 14.3 to 15.1 ms with it, 13.9 to
14.4 without) and was not kept. Steps kept before this round, each measured before and after: vectorisable row loops over
equal-length slices and `2^-t` from exponent bits (5x5 components on the bench film: 135 to 46
ms); one fused geometry-and-weight loop for a single layer (28 to 27 ms); no copy of the first
pass (3x3 on indirect: 15.5 to 12.9 ms); noiseless pixels skipped; one vector division to
demodulate and a vectorised end of row (gallery 24.7 to 23.9 ms). This round, `--denoise`'s one pass
for the direct light (criterion, the bench film: 18.2 to 14.9 ms at 256x256, 2.07 to 1.88 s at
4K; 15.6 ms and 1.93 s in the run of the table). Issue 41's check against the halves of the
samples first filtered each layer three times (whole and each half) and cost 4.9x at 256x256
(72.9 ms) and 3.6x at 4K (9.23 s). Three steps since, each measured on the bench film
(criterion, AMD EPYC, AVX2 without AVX-512):
- The whole image's filter replaced by the filtered halves weighted by their shares of the
  samples (two runs, not three): 72.9 to 51.5 ms. The check's estimate holds for that mix
  (`src/filter/cross.rs`). Kept; it costs a little error (`filter --denoise` on this table's
  renders, the mean of both seeds: paper-sky relMSE 6.16e-5 to 6.53e-5, the gallery's 9.79e-4
  to 9.97e-4, the Cornell box's 2.59e-4 to 2.60e-4; RMSE within 1.2%; the four models' ratios
  within 1.7% of before, every row still holding).
- The check's window sums in parallel, plane by plane, without image-sized buffers (one column
  sum and one row sum a thread), and the halves made in parallel: 51.5 to 44 ms (45.4 and
  43.8 in two runs). Kept; the same bits (the sums add in the same order).
- The passes compiled for AVX2 where the CPU has it (`Avx2::run` in the BVH's SIMD module,
  detected at run time; the same bits as the portable build, tested): 45.4 against 43.7 ms
  (medians of three rounds alternated, the portable build first), 5.40 against 5.20 s at 4K:
  3.7% at both sizes. Kept, at the edge of the run-to-run spread.

The next session (the same machine type, a Firecracker VM; criterion medians, rounds alternated):
- A layer past its passes (the direct light's halves after their one pass) skips its colour
  stops and is copied, not divided by its weight sum of 1: 58.8 to 60.5 ms against 52.8 to
  56.7 ms (three rounds, one binary switching between the two; a noisy hour). Kept; the same
  output (the colour is `c + 0 / h0`, exactly `c`).
- The passes' closures `inline(always)` into the AVX2 runner (without it, the rows' closure is
  called from `run_avx2`, compiled for the portable target): AVX2 against portable in one
  binary, 54.6 / 49.9 / 45.9 ms against 51.1 / 51.1 / 45.8 ms. No gain; not kept.
- A block of 8 centres with its five sums in registers across all taps of a pass, every tap's
  geometry made once per block for all layers (the step the last profile pointed to): the same
  bits (tested), but 48.6 and 51.7 ms against 46.9 and 45.1 ms for the row loops (two rounds,
  one binary). Not kept. The profile had misled: the passes' share was not the tap loop's.
- A layer that is zero everywhere (the caustics of a scene without them: the bench film, the
  Cornell box) is no longer halved, filtered as two halves and checked: 40.7 / 40.7 / 41.0 ms
  to 31.3 / 30.9 / 31.3 ms (three rounds), 4.61 to 4.09 s at 4K. Kept; the same output (a zero
  layer came back zero).

Where the time goes now (the filter's phases timed inside one warm call, 256x256): the guides
1.7 ms; demodulation 3.4 ms; the first pass 11 ms and each later one 4.6 to 5 ms (the colour
stops 0.6 ms of it); the multiply-back 1.3 ms; freeing the working buffers 4.4 ms; the check's
blend 7.7 ms. `perf stat` over the benchmark: 31% of the CPU time in the kernel, page faults
of fresh buffers and their freeing (3.1 million faults in 190 calls, about 60 MB a call). The
next step is memory: the working buffers (5 planes of each live layer, twice) reused across
passes and calls, the halves and their variances not copied, the blend's four planes made in
one buffer; then the first pass, which pays the faults of the second working buffer.

This session (the same machine type: AMD EPYC, family 23 model 1, AVX2 only, a Firecracker VM;
the phases timed inside warm calls by a temporary patch, medians of about 140 calls):
- The check's window sums by van Herk's split (each 15-pixel window the suffix of one block of
  15 plus the prefix of the next, so three additions a pixel and a direction instead of 15,
  still only the window's own pixels, in f64): the blend 4.49 and 4.42 ms against 3.81 and 3.73
  ms (two rounds alternated in one binary). Kept. The sums add in another order; a test
  compares every pixel of seven sizes with a direct sum.
- The working buffers in huge-page mappings of their own (the BVH's `Pages`): criterion 36.1,
  41.7 and 42.3 ms against 31.1, 32.3 and 36.3 ms on the heap (three rounds alternated, one
  binary). Slower; not kept.
- The phases now: the halves 1.6 ms, the guides 1.0, demodulation 3.3, the first pass 7.5, each
  later pass 3.7, the multiply-back 1.4, freeing 0.9, the blend 3.8.
- **The passes are 18.6 ms of the call:** 1.8 ms for each live layer in each pass (65,536
  centres, 8 taps each: about 3.5 ns of CPU a tap on two cores). `--denoise` runs ten of them:
  the four halves in the first pass, then the indirect light's two halves in three more.
- **What 10 ms takes:** at this rate the passes alone exceed the budget, so memory is not the
  lever. It takes fewer layer-passes (for example the direct light's check from one pass of
  each half, or the indirect light's later passes on the whole instead of the halves) or a tap
  twice as cheap. Each of those changes the error tables and must be measured against them.


**On an AVX-512 machine (2026-12-06: AMD EPYC, family 26 model 2, AVX-512, 2 cores, a
Firecracker VM; criterion medians, the two bench binaries alternated round by round):**
- Before any change (9ff9642): `--denoise` 11.8, 12.1 and 12.9 ms at 256x256 (17 to 19 ms in a
  first, noisier hour), `cross=0` 3.4 to 3.8 ms, and 2.12 s at 4K. A profile of the warm
  benchmark (`perf record`) put **about 35% of the time in the kernel**: zeroing fresh pages
  (`clear_page_erms`, 20%), page faults and unmapping, for the passes' 26%. glibc hands back
  the working planes (5 MB each) to the system at every call, so each call faults them in again.
  With `MALLOC_MMAP_THRESHOLD_` and `MALLOC_TRIM_THRESHOLD_` raised (memory kept in the
  process), the same binary took 11.4 and 11.3 ms against 17.0 and 17.6 ms.
- **The working planes kept between calls** (`src/filter/pool.rs`: the passes' two buffers,
  the colour stops, the guides, the halves' variances and the check's planes; a plane taken
  from the pool is zeroed, and the pool keeps at most 96 MB, so a 4K call keeps nothing): 12.2 /
  13.4 / 12.5 ms to 11.7 / 9.5 / 9.3 ms (three rounds; 11.8 / 12.1 / 12.9 to 10.1 / 10.2 / 9.9
  in an earlier three, with the first version, below), 4K 2.12 to 1.88 s (one round each). Kept; the same bits (the three
  denoising scenes' `filter --denoise` outputs compared, RMSE 0). On the paper-sky film,
  warm calls inside one process (a temporary loop) went to a median of 7.8 ms: the halves 0.5,
  the guides 0.4, demodulation 0.7, each pass 0.8, the multiply-back 0.4, each layer's check
  0.8 ms.
- Keeping the images too (the halves and the filtered halves, in a second pool of colours):
  10.1 / 9.7 / 8.9 / 9.2 ms against 9.8 / 9.1 / 9.2 / 9.4 ms for the planes alone (four rounds).
  No gain; not kept.
- A fresh process (`filter --json`'s `filter_seconds`, five runs a film, three rounds
  alternated, both release builds) is not helped, nor made slower: paper-sky medians 13.5 /
  13.9 / 12.1 ms before against 13.2 / 12.3 / 11.5 after, the gallery 23.6 / 21.3 / 19.2
  against 21.3 / 19.6 / 20.7, the Cornell box 12.8 / 15.3 / 12.4 against 17.5 / 13.3 / 11.8.
  There every page is new whatever the allocator does; a new plane is `vec![0.0; n]`, whose
  pages are faulted in by the threads that first write them, as before (zeroing it on the
  calling thread, as the first version did, faults every page on that one thread; it was
  changed before these runs, and not measured alone).
- **At 4K the planes are too large to keep, and the kernel takes three quarters of a call:**
  `perf record` of the warm 4K benchmark put 77.6% of the samples in the kernel (zeroing
  fresh pages 44%, faults and unmapping most of the rest), the passes about 9%: a call touches
  about 3 GB of new memory. **Planes of 32 MB and more now go in their own mappings advised for
  transparent huge pages** (the BVH's `Pages`, through `memmap2`): one fault for 2 MB. 4K: 2.10
  and 2.02 s to **1.49 and 1.43 s** (two rounds alternated). Kept; the same bits (a 4K
  `filter --denoise` of the Cornell box at 4 spp compared, RMSE 0). A fresh process at 4K
  (`filter_seconds`, three runs each, alternated): 2.87 / 3.01 / 2.83 s before, 3.07 / 2.50 /
  2.56 s after. Smaller planes keep the heap and the pool (huge pages at 256x256 were slower
  on the Zen 1 machine, above).
- **The goal on this machine:** 9.3 to 10.2 ms at 256x256, at the budget of 10 ms; 1.43 to
  1.49 s at 4K, within the budget of 1.5 s. On the Zen 1 machine of the paragraphs above it stays missed
  (31 ms measured there before this change, not measured again).
- The timings of `scripts/bench-denoise.sh` piped `filter --json` into Python, which then
  started on the cores while the filter ran: paper-sky's filter read 21 to 36 ms that way
  against 12 to 16 ms read after the run. The script now reads the JSON after the run, as does
  `scripts/bench-ab.sh` for `bench-accel`. The table's seconds above were taken the old way.

- **A regression caught and mended (2026-12-06, the next session, the same machine type).** The
  builds chosen at run time became one type (`simd::Isa`, whose `run` takes a job); the passes
  first went through it as closures, and `perf` of the benchmark showed the rows' closure
  (`run_pass::{{closure}}::{{closure}}`) outlined, compiled for the portable target, where
  b12c98c had inlined it into the AVX2 function: criterion at 256x256 11.8 / 12.7 / 13.1 ms
  against b12c98c's 9.1 / 9.4 / 9.3 ms (three rounds alternated). As jobs whose `run` is always
  inlined (`ColourStops`, `Row`): 10.5 / 8.5 / 9.1 ms against 11.3 / 10.0 / 8.5 ms for b12c98c
  in the next three rounds, and at 4K 1.25 s against 1.48 s (one round each). The closure form
  is gone from `Isa`.
- **The passes in the AVX-512 build** (`Isa::best()` instead of `Isa::avx2_or_portable()`, as
  jobs): 8.71 / 9.21 / 8.73 / 9.41 ms against 8.89 / 8.82 / 9.01 / 9.74 ms for AVX2 (four rounds
  alternated; medians 8.97 and 8.95). Not kept: the same time, and AVX2's build serves both
  kinds of machine. (A first comparison with the outlined closures, 12.1 / 12.6 / 11.1 against
  12.2 / 11.8 / 12.2 ms, measured neither build.)
- **The goal at this commit:** 8.5 to 10.5 ms at 256x256 over the seven rounds of this session's
  fixed builds, so at or inside the budget of 10 ms in six of them; 1.25 s at 4K.
- **Later the same day (the same AVX-512 machine type; `perf`, and phases timed inside 500 warm
  calls of `composite` on the bench film by a temporary patch):** the halves 0.57 ms, the guides
  0.63, demodulation 0.92, the passes 5.2, the multiply-back 0.48, the check's blend 2.3 (its
  errors 0.42, window sums 0.81, the final mix 0.83, of which 0.70 the copy of the unfiltered
  image). `perf stat`: 368 page faults a call, two fresh 786 KB images.
- **Kept (fdfe2b1):** the blend written over the first filtered half instead of a copy of the
  unfiltered image (page faults in 550 calls, the set-up's included: 202,557 to 8,927); the
  working planes taken without zeroing where they are written whole (`Plane::overwritten`: the
  passes' two buffers, the colour stops, the guides, the check's weights, the halves' variances:
  about 12 MB of `memset` a call); a layer past its passes (the direct light's halves) no longer
  copied in each later pass (2.6 MB a pass) but read from the buffer its last pass wrote. The
  same bits (`render --denoise` of the Cornell box and the gallery, `cmp`; a test covers a
  layer that ends an even and an odd number of passes early). Criterion at 256x256, five rounds
  alternated with 3389e99's build: 9.79 / 11.42 / 10.20 / 10.76 / 10.01 ms to 9.82 / 9.37 /
  9.85 / 11.01 / 10.49 ms, medians **10.20 to 9.85 ms** (0.97x); the warm-call loop 10.01 to
  9.17 ms (medians of six, 0.92x); 4K **1.58 to 1.26 s** (one round each). A fresh process
  (`render --denoise --json`'s `filter_seconds`, the Cornell box at 256x256, eight runs
  alternated, two sets): 16.3 and 16.0 ms to 16.2 and 15.8 ms, unchanged: there every page is
  new whatever the filter reuses.
- Not kept: a block of 8 centres with its sums in registers across all taps, again (as `[f32;
  8]` arrays): first 23.7 ms (closures and array maps left outlined), then 15.5 ms (lanes
  stored one by one and read back as a vector: `perf annotate` put 23% on the instruction after
  that load), then, written out, 8.57 against 8.64 ms (medians of three): the same time, as the
  attempt above found.
- Not kept: planes of 2 MB and more in huge pages and pooled (the BVH's `Pages`): a fresh
  process's page faults 13,804 to 11,299, but `filter_seconds` 17.5 and 19.0 ms against 16.2
  and 15.8 ms (medians of eight, two sets), in two modes from 13.5 to 27 ms: a huge page's
  fault zeroes 2 MB at once, and the kernel may compact memory to find one.
- Not kept: the check's window sums over two planes instead of three where every pixel has
  both halves (its count plane then says nothing): the warm-call loop 8.85 against 8.71 ms
  with two threads, 16.84 against 16.88 ms with one (medians of six, alternated). Within the
  noise; a test of the weights against windows summed directly came of it.
- **The goal at fdfe2b1:** 9.4 to 11.0 ms at 256x256 over this session's criterion rounds, so
  at the budget of 10 ms and not inside it in every round; 1.26 s at 4K, within 1.5 s.
- **Mixed pixels gated by the film's alpha (measured, not kept).** The film keeps the share of
  a pixel's samples that hit any surface (the EXR's alpha), so the step "Where the remaining
  error is" asked for can now tell a pixel between two objects (alpha 1) from one partly on the
  background. Such pixels, under `pure`, gathered from every object around them (as taps they
  stayed out of pure windows; normal stop a tenth). `filter --denoise` of this table's films
  (64 spp, seeds 1 and 2, mean RMSE / relMSE; 3389e99's filter first): the Cornell box 6.44e-3 /
  2.60e-4 to 6.42e-3 / **2.48e-4** (below OIDN's 2.51e-4), the gallery 4.51e-3 / 9.97e-4 to
  4.45e-3 / 9.72e-4, **paper-sky 3.39e-3 / 6.53e-5 to 3.47e-3 / 9.78e-5** (above OIDN's
  9.60e-5). With the normal stop whole, or three times, paper-sky stays at 8.96e-5 and 8.44e-5.
  All of paper-sky's loss is in about 50 pixels on the red object's border with the floor
  (x 99 to 162, y 162 to 174): opened, they took the floor's light into their green and blue
  (a pixel of reference 0.527 / 0.062 / 0.055 went to 0.629 / 0.126 / 0.120). A mixed pixel's
  two sides are gathered in the proportions the taps pass the stops, not in its samples'
  proportions, so it is biased wherever the two sides' light differs. The next step is that
  proportion: each object's share of the pixel (which Cryptomatte's ranks count when asked for), each
  side's gathered mean weighted by it.
- **Mixed pixels made from their sides (measured, not kept; the next session, the same machine
  type).** Each mixed pixel of a filtered layer replaced by its labelled object's share of its
  samples (coverage) times the mean of that object's pure neighbours, the other objects'
  share (alpha less coverage) times theirs, and the background's (1 less alpha) times the pure
  background's, over 3x3: the Cornell box 2.60e-4 to 2.51e-4, but the gallery 9.97e-4 to
  1.08e-3 and paper-sky 6.53e-5 to 1.07e-4 (5x5: 2.59e-4, 1.13e-3, 9.57e-5). The shares are
  right; the neighbours are not: at a contact shadow the border is darker than both sides (a
  paper-sky pixel on the red object's border with the floor, reference 0.088 in red, came out
  0.185). The filter's own rule, mixed pixels gathered only along their border, keeps them.
- **Where the gallery's error is now** (seed 1, relMSE summed over each object's pure pixels,
  `--denoise` against OIDN): the ceiling 4.81e-4 against 2.99e-4, the back wall 2.11e-4
  against 1.50e-4, of 1.03e-3 against 7.57e-4. On the ceiling the two seeds' outputs differ
  (the relMSE of half their difference) by 5.3e-5 against OIDN's 1.8e-5: three times the
  noise left. And the seeds' mean, blurred over 17x17, is off the reference by 4.7e-5 against
  1.7e-5: the error that survives a blur, with the ceiling's mean 1.2% to 1.7% below the film's
  (OIDN's 0.3%; giving each object back the film's mean would gain 1% to 2%). Smoothing harder
  does not help: the variance carried through the passes scaled by 1.5, 2 or 3 each pass, every
  scene worse (the gallery 1.03e-3, 1.07e-3, 1.13e-3); by 0.7 or 0.5, paper-sky better (6.01e-5,
  5.84e-5) and the others worse. Unchecked (`cross=0`), a fifth pass took the ceiling's noise
  from 4.9e-5 to 3.9e-5 but its blurred error from 4.1e-5 to 5.8e-5, and with the variance
  doubled as well to 1.3e-5 and 1.35e-4: the mean flattens the light's gradients as it
  widens, the more so beside the walls, where the window is one-sided.
- **Kept (b133c2c): the plane fit, `linear=P`.** From pass P on, each centre takes the value
  at its own position of the plane its taps fit by weighted least squares, with the same
  weights and a ridge of a tenth of the weight sum on the slopes, instead of their weighted
  mean. A prototype in numpy of the indirect layer's filter (the Rust filter's output
  reproduced to 2e-6; `cross=0`, seed 1): the gallery 9.64e-4 to 8.87e-4 with the ridge at
  0.1 (0.03: 9.00e-4; 0.3: 9.03e-4; none: 9.29e-4), the Cornell box 2.58e-4 to 2.38e-4,
  paper-sky 6.26e-5 to 5.68e-5; the plane's own variance for the next pass's stops, instead of
  the mean's, within 1%. In the filter, `filter --denoise` on this table's films (seeds 1 and 2,
  mean RMSE / relMSE; OIDN 2.5 on the same films: 1.49e-2 / 2.51e-4, 5.58e-3 / 7.43e-4, 5.12e-3
  / 9.60e-5):

  | setting | `cornell` | `paper-gallery` | `paper-sky` |
  | --- | --- | --- | --- |
  | no fit (fdfe2b1) | 6.44e-3 / 2.60e-4 | 4.51e-3 / 9.97e-4 | 3.39e-3 / 6.53e-5 |
  | `linear=1` (every pass) | 6.39e-3 / 2.37e-4 | 4.38e-3 / 9.08e-4 | 3.28e-3 / 5.61e-5 |
  | `linear=2` (b133c2c) | 6.39e-3 / 2.35e-4 | 4.38e-3 / 9.12e-4 | 3.29e-3 / 5.80e-5 |
  | `linear=3` | 6.39e-3 / 2.37e-4 | 4.40e-3 / 9.26e-4 | 3.33e-3 / 6.23e-5 |
  | `linear=2`, `sigma_l=8` | 6.38e-3 / 2.29e-4 | 4.35e-3 / 8.88e-4 | 3.30e-3 / 6.24e-5 |
  | `linear=2`, `cross=0` | 6.39e-3 / 2.36e-4 | 4.29e-3 / 8.77e-4 | 3.29e-3 / 5.58e-5 |
  | **`linear=2`, the ridge grown with the noise (kept)** | 6.39e-3 / **2.34e-4** | 4.38e-3 / **9.17e-4** | 3.29e-3 / **5.85e-5** |

  The Cornell box is now below OIDN's relMSE and paper-sky further below it; the gallery stays
  above, 1.23x (1.34x before). `linear=2` rather than 1: the first pass filters every
  component's halves and costs the most, for an error within 2% either way. The check costs
  the gallery 4% (`cross=0`), and the filtered halves' mix without the check's weights 1%
  (8.87e-4).
- **At few samples a fixed ridge let the slopes fit noise.** `converge` at b133c2c put the
  Cornell box's relMSE at 4 spp at 3.54e-3 (the table above, before it: 3.14e-3); renders at 4 and 16 spp (seeds 1 and
  2, the same films filtered each way, mean relMSE, Cornell box / gallery / paper-sky) put no
  fit at 4 spp at 3.31e-3 / 1.11e-2 / 2.26e-3 and the fixed ridge at **3.54e-3** (7% worse) /
  1.12e-2 / 2.20e-3. The ridge now grows with the centre's relative noise, `0.1 W (1 + K V /
  l²)`, `V` the variance carried to the pass and `l` the luminance:

  | K | 4 spp | 16 spp | 64 spp |
  | --- | --- | --- | --- |
  | no fit | 3.31e-3 / 1.11e-2 / 2.26e-3 | 7.08e-4 / 2.32e-3 / 2.77e-4 | 2.60e-4 / 9.97e-4 / 6.53e-5 |
  | 0 (the fixed ridge) | 3.54e-3 / 1.12e-2 / 2.20e-3 | 7.14e-4 / 2.28e-3 / 2.54e-4 | 2.35e-4 / 9.12e-4 / 5.80e-5 |
  | 16 | 3.39e-3 / 1.11e-2 / 2.21e-3 | | 2.34e-4 / 9.14e-4 / 5.83e-5 |
  | **32 (kept)** | 3.35e-3 / 1.10e-2 / 2.22e-3 | 6.92e-4 / 2.24e-3 / 2.59e-4 | 2.34e-4 / 9.17e-4 / 5.85e-5 |
  | 64 | 3.33e-3 / 1.10e-2 / 2.22e-3 | 6.87e-4 / 2.24e-3 / 2.62e-4 | 2.34e-4 / 9.21e-4 / 5.89e-5 |
  | 256 | 3.30e-3 / 1.11e-2 / 2.24e-3 | 6.84e-4 / 2.25e-3 / 2.68e-4 | 2.36e-4 / 9.36e-4 / 6.03e-5 |

  With 32, against no fit: at 4 spp the Cornell box 1.3% worse and the others 1% and 2%
  better; at 16 spp 2% to 7% better; at 64 spp 8% to 10% better.
- **Its cost, lever by lever** (criterion at 256x256): one loop over the eleven new sums was
  not vectorised (scalar `vaddss`): 19.5 ms against 8.4 ms; the weights kept for the other
  sums' loop, 15.5 ms; each loop making the weights again, about 12 ms; the weights made once
  and the sums in loops of a few arrays each, one of them left a closure that stayed outlined
  in the portable build, 11.8 ms, and as a function (b133c2c) 9.6 ms against 8.7 ms for
  fdfe2b1 (six rounds alternated, medians; a quieter hour). The first moments of the taps'
  values rather than of their differences from the centre (three arrays fewer to read): the
  same time, not kept. Then two steps found by `perf annotate` in code the passes do not run:
  the check's window sums took a remainder per pixel and the depth gradients a division per
  pixel for its coordinates (aa026dc: 9.73 / 10.02 / 9.35 / 11.03 ms to 8.90 / 8.84 / 8.95 /
  8.46 ms), and the gradients' steps between neighbours are now made once for both pixels in
  flat loops (ee1a77c: 10.34 / 9.60 / 9.01 / 9.31 ms to 9.97 / 8.84 / 9.10 / 8.89 ms); both
  the same bits.
- **The goal at ee1a77c**, against fdfe2b1, five rounds alternated: 9.09 / 10.63 / 9.00 /
  10.03 / 8.12 ms against 10.01 / 8.42 / 8.70 / 8.81 / 8.30 ms, medians **9.09 to 8.70 ms**:
  the plane fit is paid for, and the budget of 10 ms is met in four rounds of five. 4K: 1.57
  against 1.68 s (one round each, in an hour whose 4K samples spread from 1.13 to 2.1 s within
  one criterion run; 1.26 s for fdfe2b1 last session); later, in a quieter hour, cedc532 1.42
  and 1.50 s against fdfe2b1's 1.29 and 1.32 s (two rounds alternated): 1.1x, at the budget of
  1.5 s. A fresh process (`filter --denoise --json`'s `filter_seconds`, seed 1's film, six runs
  alternated, medians): the Cornell box 20.8 to 19.3 ms, the gallery, whose caustics are a
  third live layer, 32.9 to 35.0 ms.

**4K in bands of rows (2026-12-06; AMD EPYC, family 26 model 2, AVX-512).**
- **Where a fresh 4K call went:** `filter FILM.exr --denoise` of a 3840x2160 Cornell box at 4
  spp, `perf record` of the whole process: the kernel's `clear_page_erms` 43% of the samples,
  writing the output EXR 30%, the passes about 3%. `strace` counted 7.45 GB of fresh anonymous
  mappings of 1 MB or more: the decoder's 49 channels (1.6 GB) and our copy of them (1.6 GB),
  the film's layers, and the passes' two working buffers, 665 MB each. On this VM a fresh page
  is dear: in eleven runs before the bands the process took 8.9 to 24.6 s of wall time, 4.3 to
  21.4 s of it in the kernel, and its `filter_seconds` read 3.3 to 6.4 s, once 1.3 s.
- **Kept: the passes in bands** of 128 rows once the whole image's two buffers would pass 64 MB.
  A band demodulates the rows its passes read (15 above and below for `--denoise`'s four passes
  of three taps), runs each pass over the rows the passes after it read, and multiplies back its
  own rows; its neighbours compute those shared rows again (13% more rows through the passes at
  4K). The buffers are a band's, 50 MB rather than 1.3 GB. The same bits: `cmp` of the 4K
  outputs, and a test filtering in bands of 1 to 100 rows against the whole image under three
  settings. 256x256 is one band, as before.
- **Measured**, three rounds alternated, 6ff5160 against the bands: `filter_seconds` 5.71 /
  4.22 / 4.01 s to **1.37 / 1.49 / 1.39 s**; the whole process 17.7 / 14.8 / 14.5 s to 6.7 /
  7.4 / 7.2 s wall (18.7 / 14.0 / 13.5 s to 3.9 / 4.3 / 4.2 s in the kernel); its peak resident
  memory 4.13 to 3.19 GB. Criterion's warm 4K call (its planes come back from the pool and the
  allocator), two rounds: 1.49 / 1.46 s to **1.31 / 1.25 s**; 256x256 within the noise (8.00 /
  8.61 / 9.16 ms before, 9.05 / 8.52 / 8.81 ms after); a fresh 256x256 call of the gallery, ten
  rounds alternated, medians 38.0 and 38.8 ms. In a render: `render scenes/cornell.toml
  --width 3840 --height 2160 --spp 4 --denoise --json`, two rounds, `filter_seconds` 6.61 /
  5.51 s to **1.78 / 1.99 s**, the same image (`cmp`). At 1920x1080 (the Cornell box at 4 spp,
  a fresh `filter --denoise`, five rounds alternated, the whole image forced by a temporary
  setting against the bands): medians 0.322 s whole against **0.251 s** in bands, the same bits.
  The gallery at 4K and 2 spp (three live layers, each filtered half by half: six in the
  buffers), one run each: 8.33 s whole against **2.94 s** in bands, the same bits, and the rows
  at the bands' edges no further from their neighbours than the others (mean step 0.00367
  against 0.00355).
- **Not kept: an EXR's channels moved out of the decoder** rather than copied. It took a fresh
  4K read from 1.86 M to 1.48 M minor page faults, yet the filter after it got slower: the
  gallery's fresh 256x256 `filter_seconds`, ten rounds, median 44.3 ms against 38.0 ms, and at
  4K 4.5 to 6.1 s against 3.3 to 3.8 s. The copies' freed originals had been memory the
  allocator gave the filter's planes again, already faulted in.
- **The gallery's relMSE, the stops scanned again** (2026-12-06, a4c1efc; `filter` of the 64-spp
  films of seeds 1 and 2, means; RMSE / relMSE; OIDN on the same films: the Cornell box 1.49e-2
  / 2.51e-4, the gallery 5.58e-3 / 7.43e-4, paper-sky 5.12e-3 / 9.60e-5). `--denoise`: the
  Cornell box 6.39e-3 / 2.34e-4, the gallery 4.38e-3 / 9.17e-4 (1.23x OIDN's relMSE), paper-sky
  3.29e-3 / 5.85e-5. The indirect layer's `sigma_l` at 8, 10 and 12: the gallery 8.94e-4,
  8.93e-4 and 8.96e-4; paper-sky 6.33e-5, 6.91e-5 and 7.55e-5. Without the check against the
  halves (`cross=0`), the gallery goes to 8.76e-4 at `sigma_l` 6 and to **8.39e-4** at 10, 1.13x
  OIDN's. The check is what keeps clean third-party models from getting worse, so it stays.
  Five and six passes: the gallery 9.26e-4 and 9.53e-4. The variance carried between passes
  kept from falling below a half, 0.8 or all of the pass's input (a temporary setting): the
  gallery 9.65e-4, 1.02e-3 and 1.05e-3, and every scene worse. The colour stop tightening
  pass by pass is what works here, not what holds the error up. No setting of these stops
  reaches OIDN's relMSE on the gallery.
- **Where a fresh 4K `filter --denoise` spends its wall time now** (2026-12-06, a4c1efc; the
  Cornell box at 3840x2160 and 4 spp, 394 MB in): 14.0 to 23.4 s of wall over five runs, of which
  `filter_seconds` is 1.4 to 1.7 s. `perf record` of the whole process: deflating the output
  EXR (`miniz_oxide`, the `exr` crate's ZIP at its fixed level 4) 42% of the samples, the
  kernel clearing fresh pages 25% (almost all of them in the copy of the decoded channels),
  decoding 7%. The output's compression, one run each through a temporary setting: ZIP 23.4 s
  wall (17.2 s user) for 447 MB, PIZ 19.9 s (10.8 s) for 504 MB, RLE 15.4 s (6.5 s) for 602 MB,
  none 18.7 s (5.6 s) for 1,725 MB. Moving the decoded channels into the film rather than
  copying them, measured again now that the passes run in bands (three rounds alternated):
  14.2 to 20.2 s against 14.0 to 18.7 s wall, no difference through this machine's noise, so
  not kept. So the EXR's compression became a choice: `--exr-compression zip|piz|rle|none`
  (ZIP stays the default, for the smallest files). With it, two runs alternated: `zip` 24.8 and
  20.8 s wall (447 MB), `rle` 15.6 and 14.4 s (602 MB). Every compression reads back bit for bit (a unit test
  and a command-line test compare every channel).
- **Kept: each half's taps weighed by their luminance in the other half** (2026-12-06, 59a7bd0
  and a39493e; AMD EPYC, family 26 model 2, AVX-512). Under the check, each half of a layer's
  samples is filtered on its own. Its colour stop compared the centre's luminance with each
  tap's luminance in the same half: a weight made from the value it multiplies, so a tap far
  above the centre counts less than one as far below, and skewed noise (many samples a little
  below the mean, a few far above it) comes out darker. Now a tap's luminance is read in the
  other half, whose noise is independent; the centre keeps its own half's luminance and
  variance, blurred over 3x3 in the first pass (among same-object pixels, as the variance). A
  unit test filters light 1 under exponential noise (2 samples a half, 96x96): the mean of the
  filtered halves is 3.0% low with the old stops, 1.9% high with the centre's luminance
  unblurred (a bright centre keeps more of itself), 0.5% high with it blurred, within 4
  standard errors (2.1%), which the test asserts. `filter` of this table's films (64 spp,
  seeds 1 and 2, means; RMSE / relMSE; OIDN 2.5 on the same films: the Cornell box 1.49e-2 /
  2.51e-4, the gallery 5.58e-3 / 7.43e-4, paper-sky 5.12e-3 / 9.60e-5):

  | setting | `cornell` | `paper-gallery` | `paper-sky` |
  | --- | --- | --- | --- |
  | own stops, `sigma_l` 6 (148120e) | 6.39e-3 / 2.34e-4 | 4.38e-3 / 9.17e-4 | 3.29e-3 / 5.85e-5 |
  | centre and taps from the other half, `sigma_l` 6 (not kept: below) | 6.36e-3 / 2.20e-4 | 4.25e-3 / **8.57e-4** | 3.28e-3 / 5.96e-5 |
  | the same, `sigma_l` 5 | 6.36e-3 / 2.22e-4 | 4.24e-3 / 8.56e-4 | 3.28e-3 / 5.76e-5 |
  | taps from the other half, the centre its own, `sigma_l` 5 (59a7bd0) | 6.37e-3 / 2.30e-4 | 4.29e-3 / 8.85e-4 | 3.28e-3 / 5.78e-5 |
  | **the same, the centre blurred in the first pass (a39493e, kept)** | 6.36e-3 / **2.22e-4** | 4.24e-3 / **8.62e-4** | 3.27e-3 / **5.76e-5** |
  | the same, `sigma_l` 4.5 | 6.36e-3 / 2.24e-4 | 4.25e-3 / 8.65e-4 | 3.27e-3 / 5.68e-5 |
  | the same, `sigma_l` 6 | 6.35e-3 / 2.20e-4 | 4.26e-3 / 8.61e-4 | 3.28e-3 / 5.97e-5 |

  Also scanned on a39493e (relMSE, the Cornell box / the gallery / paper-sky), none kept: the
  plane fit from the first pass (`linear=1`) 2.24e-4 / 8.62e-4 / 5.57e-5, five passes 2.22e-4
  / 8.65e-4 / 5.82e-5, the direct light in two passes 2.21e-4 / 8.62e-4 / 5.77e-5. None moves
  the gallery; `linear=1` is 1% worse on the Cornell box and 3% better on paper-sky, five
  passes worse on two scenes, two direct passes within 0.3%.
  The gallery goes from 1.23x to **1.16x** OIDN's relMSE: still above it. At few samples the
  gain is larger (`converge`, the table above): at 4 spp the gallery 1.74e-2 / 1.10e-2 before
  against 1.49e-2 / 6.27e-3, the Cornell box 5.22e-2 / 3.35e-3 against 5.20e-2 / 2.70e-3. **Not kept: the centre's luminance and variance
  from the other half too**, though it gained most on the gallery: the Khronos models'
  DamagedHelmet came out worse than unfiltered at 4 to 256 spp (RMSE 1.025x, 1.006x, 1.009x,
  1.002x the unfiltered image's; "Denoising third-party models", below). The check estimates a
  filtered half's error by its distance from the other half, which must then be independent of
  it at each pixel; a centre weighed by the other half's luminance is not. Where it lost, a
  firefly of one half at a tap passed the other half's stop: of the indirect layer's added
  squared error at 4 spp, the worst 1% of pixels held 5.6 times the net (a pixel of reference
  0.025 went from 0.082 to 0.14). With the centre its own, every model's row holds. The
  blurred centre reads the same half only, so the check's premise is kept. Time
  (`cargo bench --bench filter`, `denoise/components` at 256x256, 148120e against a39493e, six
  rounds alternated in a quieter hour): 12.04 / 12.05 / 10.42 / 10.12 / 10.53 / 10.52 ms
  against 12.20 / 11.03 / 10.70 / 10.66 / 10.90 / 10.30 ms, a ratio of 1.02 (median of the
  pairs): the same within this machine's noise, and both at the budget of 10 ms this hour
  (9.1 to 8.7 ms in an earlier session's quieter hour). At 3840x2160, two rounds alternated:
  1.65 / 1.33 s against 1.41 / 1.39 s, within the budget of 1.5 s.

"""
FINDINGS = FINDINGS.split("\n")
PEER = "OIDN 2.5 (beauty + albedo + normal)"


def curves(root, scenes, kernel):
    """--denoise against box5 --edge-pure on L_rdd at each spp converge measured."""
    lines = [
        "**Against the best of the paper's filters at every sample count** (`converge`, 4 to 256 spp, "
        "the same renders filtered both ways; mean of the seeds; RMSE / relMSE):",
        "",
        "| scene | spp | box5 on indirect, `--edge-pure` | `--denoise` | --denoise no worse in both |",
        "|---|---|---|---|---|",
    ]
    for s in scenes:
        path = os.path.join(root, s, "converge", "results.csv")
        if not os.path.exists(path):
            continue
        cells = collections.defaultdict(list)
        for r in csv.DictReader(open(path)):
            cells[(int(r["spp"]), r["filter"], r["target"], r["edge_aware"])].append((float(r["rmse"]), float(r["relmse"])))
        mean = {k: tuple(sum(x[i] for x in v) / len(v) for i in range(2)) for k, v in cells.items()}
        for spp in sorted({k[0] for k in mean}):
            box = mean.get((spp, "box5", "indirect", "pure"))
            ours = mean.get((spp, kernel, "components", "pure"))
            if not box or not ours:
                continue
            ok = ours[0] <= box[0] and ours[1] <= box[1]
            lines.append(
                f"| `{s}` | {spp} | {box[0]:.2e} / {box[1]:.2e} | {ours[0]:.2e} / {ours[1]:.2e} | {'yes' if ok else '**no**'} |"
            )
    return lines + [""]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("rows")
    ap.add_argument("--spp", type=int, required=True)
    ap.add_argument("--seeds", type=int, required=True)
    ap.add_argument("--reference-spp", type=int, required=True)
    ap.add_argument("--regions", help="regions.py's table of the gallery's textured regions")
    ap.add_argument("--curves", help="the output directory: <scene>/converge/results.csv")
    ap.add_argument("--figures", help="the scenes whose figures are in docs/results/denoise-<scene>-*.png")
    ap.add_argument("--denoise-kernel", required=True, help="--denoise's filter as converge names it")
    args = ap.parse_args()

    cells = collections.defaultdict(list)
    scenes, methods = [], []
    for r in csv.DictReader(open(args.rows)):
        key = (r["scene"], r["method"])
        cells[key].append((float(r["rmse"]), float(r["relmse"]), float(r["seconds"])))
        if r["scene"] not in scenes:
            scenes.append(r["scene"])
        if r["method"] not in methods:
            methods.append(r["method"])
    mean = {k: tuple(sum(x[i] for x in v) / len(v) for i in range(3)) for k, v in cells.items()}

    out = ["## Denoising: the à-trous filter against a learned denoiser", ""]
    out.append(
        f"`scripts/bench-denoise.sh`: {args.spp} spp (sobol, the default), the mean of seeds 1 to {args.seeds}, "
        f"against a {args.reference_spp}-spp reference (independent sampling, seed 1000), 256x256. Every method "
        "filters the very same renders. RMSE is given as a ratio of the unfiltered RMSE, then RMSE / relMSE; "
        "seconds are the filter's alone (OIDN's `execute()` on 2 threads; lightsplit's `filter --json`). "
        "The reference's own noise is part of every figure: at 4096 independent samples it is about 1/8 of "
        "the unfiltered RMSE at 64 independent samples."
    )
    out.append("")
    out.append("| method | " + " | ".join(f"`{s}.toml`" for s in scenes) + " |")
    out.append("|---|" + "---|" * len(scenes))
    for m in methods:
        row = [m]
        for s in scenes:
            if (s, m) not in mean:
                row.append("-")
                continue
            rmse, rel, sec = mean[(s, m)]
            base = mean.get((s, "unfiltered"), (rmse,))[0]
            row.append(f"{rmse / base:.2f}x: {rmse:.2e} / {rel:.2e}, {sec * 1000:.0f} ms")
        out.append("| " + " | ".join(row) + " |")
    out.append("")
    verdicts = []
    for m in methods:
        if m in ("unfiltered", PEER):
            continue
        wins, losses = [], []
        for s in scenes:
            if (s, m) not in mean or (s, PEER) not in mean:
                continue
            (r, q, _), (pr, pq, _) = mean[(s, m)], mean[(s, PEER)]
            for metric, a, b in (("RMSE", r, pr), ("relMSE", q, pq)):
                (wins if a <= b else losses).append(f"{s} {metric} {b / a:.2f}x" if a <= b else f"{s} {metric} {a / b:.2f}x worse")
        if losses:
            verdicts.append(f"- **{m}**: not at or below OIDN everywhere: {', '.join(losses)}; better in {', '.join(wins) or 'nothing'}.")
        else:
            verdicts.append(f"- **{m}**: at or below OIDN in both metrics on every scene ({', '.join(wins)}).")
    out += ["Against OIDN (a factor is OIDN's error over ours):", ""] + verdicts + [""]
    if args.curves:
        out += curves(args.curves, scenes, args.denoise_kernel)
    if args.regions and os.path.exists(args.regions):
        out += [
            "**Textures stay sharp.** The gallery's textured regions alone (seed 1, object IDs), RMSE / relMSE "
            "against the reference in the region, and the detail kept: the correlation of the image's high-pass "
            "(minus its 3x3 blur) with the reference's, inside the region (1 all of it, 0 a blur; noise lowers it "
            "too):",
            "",
            open(args.regions).read().rstrip("\n"),
            "",
            "![The middle picture, teapot, marble pedestal and carpet: unfiltered, --denoise, OIDN 2.5, the "
            "reference](results/denoise-gallery-crops.png)",
            "",
            "*Left to right: unfiltered, `--denoise`, OIDN 2.5, the reference (3x, nearest neighbour).*",
            "",
        ]
    if args.figures:
        out += [
            "**Difference images** (the paper's Figure 6: white where the filtered image agrees with the reference, "
            "black at the unfiltered image's 99th-percentile difference, one scale per scene; 64 spp, seed 1) and "
            "**error against time** (`converge`: render and filter seconds, every filter on every sample count):",
            "",
            "| scene | unfiltered | box5 on indirect, `--edge-pure` | `--denoise` | RMSE against seconds |",
            "|---|---|---|---|---|",
        ]
        for s in args.figures.split():
            img = lambda kind: f"![{s} {kind}](results/denoise-{s}-{kind}.png)"
            out.append(
                f"| `{s}` | {img('diff-unfiltered')} | {img('diff-box5')} | {img('diff-denoise')} | {img('error-vs-time')} |"
            )
        out += [""]
    out += FINDINGS
    sys.stdout.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
