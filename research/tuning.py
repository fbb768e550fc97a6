"""The tuning set of the candidate defaults (`research.candidates`): every setting is chosen here,
never on a reported figure.

Disjoint from every reported column:

- repetition streams (`research.repetitions`, 8 performances, the benchmark's `StreamSettings`) of
  segments the repetition benchmark does not use, seeds 100, 101, 102 (15 streams):
  climb_1 12.9-15.9 s, climb_3 11.3-14.3 s, omomo_sub3 0-3 s (other takes and another person than the
  benchmark's climb_0/2/4 and omomo_sub10), cmu_walk 11.9-14.9 s and kneel 11.7-14.2 s (the benchmark
  cuts cmu_walk 4.4-7.4 s and kneel 4.1-7.1 s: no frame in common). The segments were picked like the
  benchmark's (most arm motion per second, end pose near the start pose) among windows outside those.
- the demonstrator cold start on `raise_lateral_both` and `wave_both` (3 subjects x 10 repetitions,
  demonstrator seed 0, one online pass over each pattern's 30 recordings from scratch); the reported
  cold start is `raise_front_both`.
- constraints only (never optimised): MAE <= 1.02 x hold-last at every step on the sudden-jump stream
  of `test/test_default_predictor.py` with seeds 100-102, and on the real clips, one pass each and,
  from round 5 on, each climbing take learned after the other four (the reported `experiment real`
  conditions: used as a pass/fail bound, as the issue allows).

`python -m research.tuning [--real] NAME...` scores registry names and the variants in `VARIANTS`.
The baselines every candidate must beat per stream (`BASELINES`) include the default's own ungated
experts (`experts_ungated`) and the gated network alone (`gated_llm_gwr`).

Chosen here: `cand_experts` (blend decay 0.99, gate decay 0.95, prior 0.001, confidence 1): pooled
0.632 x hold at 600 ms on the 15 tuning streams (RLS-AR 0.674, direct linear 0.692, the default
0.736), below every baseline on 12 of 15 (behind on climb_3 s102, cmu_walk s100 and s102 by at most
0.014), learning curve 1.006 / 0.809 / 0.577 / 0.538 x hold on performances 1-4; cold start 0.1620 /
0.2183 rad (RLS-AR 0.1623 / 0.2295); at most 1.003 x hold at any step on the jump streams. It fails
the real-clip bound (1.19 x hold on omomo_sub10 one pass; 1.09 x even behind the default's gate):
the linear experts' errors on real clips are what the faster gate lets through. Not a default yet.

Round 2 (the `c_*` variants; the real clips one pass run with every measurement, `--real`): choosing
one expert per step instead of averaging (`c_choose*`, hold-last as an expert, hysteresis 0.1) loses:
0.686-0.707 pooled, because hold-last's record from the first performance keeps it chosen through
most of the second (curve 0.98-1.00 there); blending only the experts better than hold (`c_below*`)
0.685-0.690, and up to 1.10 x hold on omomo_sub10. Scaling the network's error by its winning
neuron's record (`c_track`, `c_g_track`, `c_g_ug_track`) or favouring it (`c_fav_choose`, `c_g_fav`,
`c_g_ug_fav`) changes the pooled ratio by -0.001..+0.008: no gain. What wins is a gate around each
expert with the experts' short memory (decay 0.95, prior 0.001, confidence 1; with decay 0.99
`c_g_mg_fast` 0.684): `cand_gated_experts` (`c_g_fast`): pooled 0.648, curve 1.000 / 0.904 / 0.605 /
0.540, below every baseline on 6 of 15 (worst margin +0.025), cold start 0.1578 / 0.2175 (RLS-AR
0.1623 / 0.2295), at most 1.003 x hold at any step on the real clips and the jump streams. Without
the outer gate (`c_g_ug`, `c_g_ug_pw2`) 0.642-0.643 but up to 1.014-1.016 x hold on climb_2: too
close to the 1.02 bound to choose. Still above round 1's `cand_experts` (0.632) on the tuning streams.
Sharper weights among the gated experts (1 / MSE^p, `c_g_fast_pw*`): p = 2, 4, 8, 16 give 0.647, 0.645,
0.644, 0.643 pooled, below every baseline on 6, 6, 8, 10 of 15, cold start down to 0.1515 / 0.2093,
worst step 1.003-1.008 x hold; favouring the network on top (`c_g_fast_pw4f`) 0.656. Chosen:
`cand_sharp_experts` (p = 16), curve 1.000 / 0.890 / 0.571 / 0.538. The demonstrator held-out
figures (`experiment compare`, full) were checked on p = 1, 2, 4, 8, 16 and `c_g_fast_pw4f` as a
pass/fail bound: p = 1 0.142 / 0.153, p = 16 0.128 / 0.142 against the default's 0.127 / 0.140: still
just above it, so not a default yet.

Round 3, the default (`gwr_experts`): the network (the default's own order-4 model instead of the long
read-out), RLS-AR, direct linear and a new expert, the snippet memory (`default_predictor/memory.py`),
each behind a gate with the experts' settings, weighted 1 / MSE^p. Measured on the 15 tuning streams:
the memory alone (k 3, velocity weight 1) learns fast (curve 1.25 / 0.71 / 0.65 / 0.62) but stays above
RLS-AR from the third performance on (0.61 against 0.53): it is an expert, not a predictor on its own.
Least-squares stacking of the experts (ridge weights fitted to the observed displacements, any sign;
a prototype not kept) instead of 1 / MSE^p loses: 1.38 x hold on the first performance, 0.676-0.703
pooled. With the memory as a fourth member (p 16): 0.636 (velocity weight 1), 0.632 (0.5, kept);
looser member gates (confidence 0.5) 0.634 but 1.03-1.06 x hold on omomo_sub10: refused.
A member whose model predicts nothing (its window refilling after a gap or at a new sequence) used
to be scored as holding the pose, which pushed the weights to the linear experts wherever sequences
are short; it is now left out (`hold_when_silent=False`). Then, without a last gate: p 16 with a
~100-frame record (decay 0.99) 0.627, below every baseline on 13 of 15, but up to 1.040 x hold at some
step on omomo_sub10; p 4 with decay 0.995 0.624, 14 of 15, up to 1.021 x. The demonstrator check on
seed 7 (the demonstrator's tuning data; `experiment compare --seed 7`'s splits): every variant of the
experts is 3-5 % above the gated network alone on the held-out repetitions and person (0.1352-0.1374
against 0.1300; decay 0.95 worst, 0.99-0.999 alike) and above it on every pattern from scratch.
Chosen: p 4, decay 0.995 and a last gate on the weighted prediction (prior 0.001, z 1): 0.628 pooled,
below every baseline on 12 of 15 (worst margin +0.008), curve 1.000 / 0.854 / 0.571 / 0.522, at most
1.003 x hold at any step on the real clips and the jump streams, cold start 0.1596 / 0.2134 (RLS-AR
0.1623 / 0.2295). The default gate on the combination instead (prior 0.01, z 2): 0.634, 9 of 15.
Around the chosen point (with the ungated experts among the baselines, the default is below every
one on 8 of 15): the last gate's bound z 0.5 or 0 gives 0.627 / 0.626 pooled, 2nd performance 0.844
/ 0.836 against 0.854, worst step 1.003-1.004 x hold: within the noise of one run, not adopted; its
decay 0.97 0.630; stricter member gates (z 1.5, last gate z 0) 0.631.

Round 4 (the `r4_*` variants, `research/safety.py`): what the gates cost and cheaper ways to be safe.
Every variant has the memory's copy rule and the network's settings chosen by `experiment tune` on
the demonstrator's tuning recordings (rate 0.2, recruit_surprise 6), and round 3's member gates (`R3`,
a fixed ~20-frame memory) unless it is named `r4_warm*`. `--demo` adds the demonstrator check: per
pattern (wave_one, raise_front_both, raise_lateral_both), 5 epochs over 3 repetitions of 2 people of
seed 7's recordings, then their unseen repetitions frozen; MSE at 600 ms as a share of holding's.
Round 3's default there (`r4_r3`): 0.628 pooled, curve 1.000 / 0.854 / 0.570, cold start 0.1589 /
0.2126, demonstrator check 0.586 (the gated network 0.535, RLS-AR 0.539): the gates cost the second
performance (the experts ungated: 0.689) and the member gates' short memory costs the demonstrator.
- Where the second performance goes: without the last gate 0.826 (0.624 pooled) but 1.022 x hold at
  some step on omomo_sub10; the member gates hold back the rest.
- Hold-last as a fifth member instead of member gates: 0.631 and 1.353 x hold on a jump stream
  without the last gate, 0.640 and 1.120 x on omomo_sub10 with it. Gates on the linear members only:
  0.627 and 1.038 x (0.619 and 1.285 x without the last gate); the memory ungated: 0.627, 1.012 x,
  second performance 0.865. None gains within the 1.02 bound.
- Shrinking the weighted prediction by how much the members disagree, a Wiener factor
  |d|^2 / (|d|^2 + var) per step, instead of gates (`AgreeingExperts`, `r4_agree`): 0.621 pooled,
  second performance 0.731, the best cold start (0.1443 / 0.2086), but 1.276 x hold on a jump stream,
  where every expert agrees on extrapolating the jump; behind the last gate 0.629 and 1.064 x on
  omomo_sub10, but 0.450 on the demonstrator check, the best of any method; behind the member gates
  0.640. Open: a disagreement shrinkage that keeps the 1.02 bound.
- The memory silent unless its nearest key is within 1, 2 or 4 x the motion scale (a prototype not
  kept): 0.638, 0.632, 0.626 against 0.628: no gain.
- The member gates' memory, fixed: decay 0.9 0.632, 0.98 0.638, 0.99 0.652 (second performance 0.831,
  0.891, 0.904; the longer memories are better from the fifth performance on and on the demonstrator
  check: 0.650, 0.550, 0.534); the library's gate on every member 0.662 (0.530); each member behind a
  short and a long gate, the experts weighting all eight (`two_gates`) 0.636 (0.555). Sharper or
  slower weights (power 8, decay 0.999): 0.628 / 0.629 (0.617 / 0.577).
- A memory that warms up (`GateParams.warmup`: the long memory's decay goes from 0.95 to D over the
  first W scored frames): W 200 / 400 / 800 with D 0.99: 0.627 / 0.626 / 0.627; starting at 0.93
  (W 400, D 0.995) 0.623 but 1.004 x hold; W 400, D 0.995 (`r4_warm400_995`): 0.626 pooled, curve
  1.000 / 0.860 / 0.577 / 0.521, below every baseline (its ungated experts among them) on 8 of 15
  streams (worst margin +0.020), cold start 0.1537 / 0.2079 (RLS-AR 0.1623 / 0.2295), at most 1.001 x
  hold at any step on the real clips and the jump streams, demonstrator check 0.526 (round 3's default
  with the network's former settings, `r3_default`: 0.522).
- The network's settings in the default: `experiment tune` chose rate 0.2 and recruit_surprise 6 for
  the gated network on seed 7's held-out repetitions (by 0.5 %), but as the default's expert the
  former rate 0.1 and recruit_surprise 9 do better on the demonstrator check and as well elsewhere
  (one run with `--demo`, so its own list of methods: 0.417 against 0.485, the gated network 0.526;
  pooled 0.627 against 0.626, cold start 0.1542 / 0.2085 against 0.1537 / 0.2079, worst step 1.001).
  Chosen: the warm-up (W 400, D 0.995) with the former network settings (`gwr_experts`;
  `settings.EXPERT_NETWORK`). The demonstrator check's figures compare only within one run: a method
  that predicts on fewer frames shrinks the frames every method is scored on.
- The direct linear model's prior variance, which the demonstrator cannot rank (`experiment tune`):
  delta 0.1 / 1 / 10 give the `linear` baseline 0.722 / 0.692 / 0.744 here (1 kept).

Round 5 (the `r5_*` variants and `D:`/`G:` settings, `--real --demo`): the gates' short memories, and
trusting the experts where the movement is recognised. Round 4's default (`r5_round4`): 0.627 pooled,
curve 1.000 / 0.860 / 0.578 / 0.521, cold start 0.1542 / 0.2085, worst step 1.001, demonstrator check
0.417; its experts ungated 0.628, curve 1.220 / 0.688 (the gates still cost the second performance: on
it every member gate is shut for its first 15-50 frames, by the first performance's errors).
- The short memories (`fast_*`), until now chosen on the real clips: the member gates' `fast_decay` 0 /
  0.8 / 0.9 / 0.95 give 0.627 / 0.628 / 0.627 / 0.626 pooled, demonstrator check 0.416-0.417, but 0
  lets omomo_sub10 reach 1.021 x hold; `fast_step` 0 0.628 and 1.021 x; `fast_confidence` 1 0.647. The
  last gate's: `fast_decay` 0 / 0.8 / 0.95 0.627 alike, `fast_step` 0 0.628, `fast_confidence` 1 0.630.
  The gated network's gate (`G:`): `fast_decay` 0 / 0.8 / 0.9 / 0.95 give 0.729 / 0.730 / 0.729 /
  0.729 pooled (demonstrator check 0.575 / 0.507 / 0.526 / 0.552), `fast_step` 0 0.732, `fast_confidence`
  1 0.742; its long memory 0.97 / 0.99 / 0.995 0.708 / 0.729 / 0.743 (check 0.547 / 0.526 / 0.527);
  prior 0.001 with z 1 0.719 but 1.022 x hold on omomo_sub10. The tuning set confirms the short
  memories (0.9, step 1, z 0) within 0.001 of the best everywhere: kept. No single long memory of the
  gated network wins both the streams and the demonstrator check: kept at 0.99.
- A standard error of alpha robust to frames where the model predicted no move (a sandwich estimate;
  a prototype not kept): 0.625 on the last gate (worst 1.004), 0.626 on both gates (1.028 x), 0.627
  on the member gates (1.020 x), 0.752 on the gated network: no gain.
- The gated and the ungated members' weightings as two experts of a third weighting (decay 0.995 / 0.95
  / 0.9): 0.629 / 0.627 / 0.626, and 1.098 x hold on omomo_sub10.
- **Recognition** (`default_predictor/recognition.py`): the ungated weighting where the snippet memory's
  nearest key (copies aside) is within a radius x the motion scale per coordinate, the gated one
  elsewhere. Without the last gate, radius 2: 0.615 pooled, curve 1.003 / 0.789, cold start 0.1467 /
  0.2073, demonstrator check 0.406, but 1.048 x hold on a jump stream (there the motion scale is set by
  the jumps, so a radius of it is wide: the likely cause, not measured); radius 1 0.625. Behind the
  last gate (`r5_radius*`):
  radius 1.5 / 2 / 3 / 4 / 6 give 0.623 / 0.618 / 0.611 / 0.611 / 0.617 pooled (0.6105 / 0.6111 at 3 / 4),
  worst step 1.002 / 1.005 / 1.007 / 1.007 / 1.020; radius 3: curve 1.002 / 0.757 / 0.573 / 0.523,
  cold start 0.1476 / 0.2079, check 0.414, below every baseline (its ungated experts and round 4's
  default among them) on 14 of 15 streams. Choosing between the two weightings by their records on the
  recognised frames instead (decay 0.95 / 0.99, `r5_blend*`): 0.615 / 0.615. The ungated weighting's
  record (radius 3) forgetting at 0.95 / 0.97 / 0.98 / 0.99 / 0.995 per scored frame: 0.6053 / 0.6053 /
  0.6060 / 0.6077 / 0.6105 pooled, cold start 0.1534 / 0.2167, 0.1515 / 0.2128, 0.1503 / 0.2104,
  0.1488 / 0.2084, 0.1476 / 0.2079, check 0.400-0.414. Rule: the lowest pooled ratio, and among the
  values within 0.001 of it the best cold start: 0.98 (0.606 pooled, curve 1.002 / 0.752 / 0.554 /
  0.512, cold start 0.1503 / 0.2104, worst step 1.006 x hold, check 0.402).
- **A take learned after the others** (the bound's new condition, `--real`): there the memory
  recognises the climbing motion on every frame, and the experts ungated are worse than holding at the
  longer steps (1.046 x at 600 ms on climb_3; round 4's default 1.005): the last gate's ~100-frame
  record from the other takes keeps it open. Guards measured (all with radius 3, decay 0.98): choosing
  between the weightings by their records on recognised frames (`r5_blend*_98`, decay 0.95 / 0.99,
  power 16) 0.612-0.613 pooled, 1.024-1.028 x; the ungated weighting behind a gate with the member
  gates' settings that scores only recognised frames (a prototype not kept) 0.616, 1.037 x, and 0.875 on
  the demonstrator check; the last gate's short memory on every step's own record (`gate.fast_step` 0)
  0.608, 1.048 x. The last gate's long memory: decay 0.95 / 0.97 / 0.98 / 0.99 give 0.611 / 0.608 /
  0.607 / 0.606 pooled and 1.013 / 1.017 / 1.026 / 1.046 x hold at worst (with `fast_step` 0: 0.612 /
  0.610 / 0.609 and 1.011 / 1.007 / 1.023). Rule: the lowest pooled ratio within the bound. That was
  decay 0.97 (0.608, 1.017 x), but `experiment real` measured the same take at 1.0204 x (it scores
  the frames every one of its methods predicts, a different set): the bound needs a margin of the
  harness's. Among the points at most 1.01 x here, the lowest pooled: decay 0.97 with `fast_step` 0.
  Chosen (the default: `recognition.radius` 3, `recognition.decay` 0.98, `gate.decay` 0.97,
  `gate.fast_step` 0): 0.610 pooled, curve 1.001 / 0.752 / 0.555 / 0.513, cold start 0.1539 / 0.2115
  (RLS-AR 0.1623 / 0.2295), worst step 1.007 x hold (the left-out climb_3), below every baseline (its
  ungated experts among them) on 13 of 15 streams (worst margin +0.012), demonstrator check 0.426
  (round 4's default 0.422 in the same run, the experts ungated 0.415): on the demonstrator the switch
  costs a little (not analysed further).

Round 6 (`D:` settings and `r6_round5`, round 5's default, `--real --demo`): the last gate, and the
memory's settings never swept. Round 5's default: 0.6097 pooled, curve 1.001 / 0.752, cold start
0.1539 / 0.2115, worst step 1.007, demonstrator check 0.426 (its experts ungated 0.415).
- Where the second performance goes (the three walking streams, `cmu_walk` s100-s102): the memory
  recognises 97-100 % of its frames, and the switch alone (without the last gate) is at 0.510 / 0.656 /
  0.532 x hold there, below the ungated experts (0.497 / 0.656 / 0.530 as a baseline), but the default
  is at 0.542 / 0.752 / 0.684: the last gate shuts at step 6 for ~10 frames after the movement's onset.
  Its record at that moment is the first performance's, where the gated weighting it judged had mostly
  held the pose (little evidence, a large standard error).
- The memory (never swept before): `insert_scale` 0.25 / 0.5 / 1.0 give 0.6097 / 0.6097 / 0.6093
  pooled; `k` 2 / 3 / 5 0.6126 / 0.6097 / 0.6118; `future` 18 0.6099 (cold start 0.1564 / 0.2155);
  speed ratios [0.5, 2.0] / [0.6, 1.6] / [0.7, 1.4] 0.6116 / 0.6097 / 0.6089; `velocity_weight` 0.25 /
  0.5 / 1.0 0.6092 / 0.6097 / 0.6239. Nothing gains 0.001: kept (the lags (1, 2, 4) stay unswept).
- The single last gate: `confidence` 0.5 / 0 give 0.6079 / 0.6064 pooled, worst step 1.008 / 1.011;
  `prior` 0.0001 0.6097; no short memory (`fast_decay` 0) 0.6085 but 1.022 x on the left-out climb_3;
  `decay` 0.95 0.6119; a warm-up from 0.9 over 200 frames 0.6107, 1.012 x.
- **A last gate per weighting** (`recognition.separate_gates`): each weighting behind its own last gate,
  which scores it only on the frames it is returned on (the ungated one where the motion is
  recognised), so neither is judged by the other's record. With `confidence` 1 / 0.5 / 0: 0.6093 /
  0.6074 / 0.6067 pooled, worst step 1.003 / 1.006 / 1.019, cold start 0.1444 / 0.2110, 0.1441 /
  0.2108, 0.1438 / 0.2106, demonstrator check 0.414 (all three). Prototypes not kept (`research/safety`
  before this round): the gated weighting's gate scoring it on every frame instead, confidence 1 / 0.5
  / 0.25 / 0: 0.6093 / 0.6073 / 0.6070 / 0.6067, worst 1.003 / 1.006 / 1.011 / 1.019, cold start
  0.1474 / 0.2108 at 0.5, check 0.407 (a first measurement of its check read 1.02: the prototype's
  views were closures, which a deep copy did not follow; the library's are bound methods); with the
  1-step short memory (`fast_step` 1) 0.6077, 1.012 x; and a gate that trusts the ungated weighting
  before any evidence (a pseudo-observation of a perfect prediction: trust 1 / 0.5) 0.6104 / 0.6095.
  Rule as in round 5: the lowest pooled ratio at most 1.01 x hold at every step here, then among
  values within 0.001 of it the best cold start. Chosen (the default: `recognition.separate_gates`
  true, `gate.confidence` 0.5): 0.607 pooled, curve 0.999 / 0.736, cold start 0.1441 / 0.2108
  (RLS-AR 0.1623 / 0.2295; round 5 0.1539 / 0.2115), worst step 1.006, below every baseline but
  round 5's default on 13 of 15 streams (behind on omomo_sub3 s100 and cmu_walk s102 by 0.003 and
  0.002; round 5: 0.004 and 0.012), demonstrator check 0.414 (round 5 0.426, the experts ungated 0.415).

Round 7 (`r7_round6` is round 6's default): what still holds the second performance back, the motion
scale, and the memory's key lags, never swept before. Round 6's default: 0.6074 pooled, below every
baseline (its own ungated experts among them) on 13 of 15 streams, cold start 0.1441 / 0.2108, worst
step 1.006, demonstrator check 0.414.
- The ungated weighting's gate with its own bound (the gated weighting's kept): `confidence` 0 / 0.25 /
  0.5 at `prior` 0.001 and 0 / 0.5 at 0.0001 give 0.607 pooled in every case, the second performance
  at 0.732 / 0.733 / 0.736 / 0.731 / 0.735, worst step 1.019 / 1.011 / 1.006 / 1.021 / 1.007 (the jump
  streams, then climb_3 left out). Its bound is not what holds the onset back: a 6-step prediction is
  scored 6 frames after it is made, so on the first recognised frames the gate has nothing to judge.
- Per member on the walking streams' second performance (diagnosis): the snippet memory is at 0.52 /
  0.64 / 0.54 x hold without its gate (0.56 / 0.82 / 0.67 with it), RLS-AR at 0.46 / 0.72 / 0.59, and
  the members' weighting without gates (`experts_ungated`) at 0.497 / 0.656 / 0.530; the default
  (0.557 / 0.697 / 0.621) loses the difference in the ~6-10 frames after the onset, shrunk towards the
  pose by a gate with no scored frames yet.
- Shrinking the ungated weighting towards the gated weighting's prediction where its gate is unsure,
  instead of towards the pose (replayed from recorded outputs, not a harness run): 0.733 -> 0.727 on the
  second performance, 0.609 -> 0.605 as a mean of the streams' ratios. Too small for another state in
  the checkpoint.
- The memory's motion scale is a running mean that starts at the noise floor and reaches the motion's
  after ~1,000 frames, so on a new person (and on every tuning stream, 300-400 frames) the memory
  stores nearly every frame and recognises strictly. An unbiased mean (the plain mean until it has
  1,000 changes) puts the walking streams at 0.543 / 0.574 / 0.546 against 0.505 / 0.538 / 0.528;
  radius 1.5 / 1 0.523 / 0.519 on s100 (unchanged on the others); with `insert_scale` 0.15 and radius
  1 / 0.5 0.508 / 0.550 / 0.535 and 0.519 / 0.544 / 0.528. The slow start is what helps a new person:
  kept.
- **The memory's key lags** (`memory.longest_lag`; the lags below were measured by setting the module's
  constant before the setting existed): the changes over (1, 2) / (1, 2, 3) / (2, 4) / (1, 2, 4) /
  (1, 3, 6) / (1, 2, 4, 6) / (1, 2, 4, 8) / (1, 3, 6, 8) / (1, 2, 4, 8, 12) frames give 0.6108 /
  0.6096 / 0.6077 / 0.6074 / 0.6046 / 0.6042 / 0.6013 / 0.6015 / 0.6022 pooled; below every baseline
  on 14 / 14 / 13 / 13 / 15 / 15 / 15 / 14 / 14 of 15 streams; worst step 1.011 / 1.012 / 1.007 /
  1.006 / 1.007 / 1.012 / 1.007 / 1.007 / 1.009; cold start 0.1528 / 0.2112, 0.1490 / 0.2104, 0.1444 /
  0.2118, 0.1441 / 0.2108, 0.1395 / 0.2089, 0.1399 / 0.2072, 0.1429 / 0.2075, 0.1419 / 0.2072, 0.1529
  / 0.2045; demonstrator check 0.429 / 0.407 / 0.403 / 0.414 / 0.420 / 0.423 / 0.432 / 0.428 / 0.406.
  With (1, 2, 4, 8), `velocity_weight` 0.35 / 0.7: 0.6007 (worst 1.016 on climb_3 left out) / 0.6098.
  Rule as before, with the streams won breaking the tie of (1, 2, 4, 8) and (1, 3, 6, 8) (0.6013 /
  0.6015; (1, 3, 6, 8) has the better cold start by 0.001 but ties RLS-AR on omomo_sub3 s100). Chosen:
  `longest_lag` 8, the changes over 1, 2, 4 and 8 frames (a 9-frame history, against 5): 0.601 pooled,
  curve 1.000 / 0.733 / 0.549, below every baseline on all 15 streams, cold start 0.1429 / 0.2075,
  worst step 1.007. What it costs: the demonstrator check goes from 0.414 to 0.432 (4 % more squared
  error on the demonstrator's held-out recordings after training; not traced further).

Round 8 (`r8_round7` is round 7's default): the settings chosen with the 5-frame key, swept again with
the 9-frame one, and the network expert's regressor, never swept in the default. Round 7's default:
0.6013 pooled, cold start 0.1429 / 0.2075, worst step 1.007, demonstrator check 0.432.
- `recognition.radius` 2.5 / 3.5 / 4: 0.6068 / 0.6004 / 0.6011 pooled, worst step 1.007 / 1.017 /
  1.016 (the wider radii break the bound on climb_2 and on climb_3 left out); `memory.velocity_weight`
  0.35 / 0.75: 0.6007 (1.016 x) / 0.6120; `memory.k` 5: 0.6033; `experts.power` 8: 0.6105, check
  0.489; the network's global read-out over 4 frames (`network.global_order`): 0.6020.
- **The network's regressor** (`network.order`, 4 frames since round 3): 6 / 8 frames give 0.6012 /
  0.6038 pooled, curve 1.000 / 0.737 / 0.549 and 1.000 / 0.757 / 0.548, worst step 1.008 / 1.005,
  cold start 0.1404 / 0.2045 and 0.1376 / 0.2164, demonstrator check 0.416 / 0.379; order 6 below
  every baseline on 15 of 15 streams (round 7's default 14 in this run).
- Rule as before (the lowest pooled ratio at most 1.01 x hold at every step, then the best cold start
  among points within 0.001 of it). Chosen: `network.order` 6: 0.601 pooled, cold start 0.1404 /
  0.2045, worst step 1.008, and half of round 7's loss on the demonstrator check back (0.416).

Round 9 (`r9_round8` is round 8's default): the onset of a recognised movement. Round 8's default:
0.6012 pooled, curve 1.000 / 0.737 / 0.549, cold start 0.1404 / 0.2045, worst step 1.008, check 0.416;
its experts ungated 0.631 (curve 1.311 / 0.692).
- Where the second performance goes (diagnosis, the walking streams `cmu_walk` s100-s102): the default
  0.555 / 0.676 / 0.558 x hold on it, its experts ungated 0.474 / 0.658 / 0.533. The ungated weighting's
  gate has no record when it begins (nothing of the first performance is recognised); the pause before
  it is recognised (the start pose), and there the weighting predicts the movement to begin, as it did
  after that pose the first time, while the pause goes on: on s101 step 6's least-squares shrinkage is
  0.02-0.09 at the onset (S_xx 2.5 rad^2 of wrong moves), its alpha 0.17 four frames after it and 0.8
  eleven frames after it, while step 1's record follows the movement within a frame or two. From the
  third performance on the switch returns the ungated weighting with alpha ~1, and what is left against
  the ungated experts is its shorter record (decay 0.98 against 0.995), either sign per performance.
- Not recognising a pause (`travel`, how far the pose moved over the key's longest lag, below c x
  the motion scale; a prototype not kept): c 2 / 3 / 4.5 give 0.602 / 0.604 / 0.608 pooled, second
  performance 0.739 / 0.757 / 0.786, worst step 1.034 / 1.010 / 1.014 (climb_3 left out). The ungated
  weighting's gate split in two by the same c (still, moving; a prototype): c 1 / 2 / 3 / 5 give 0.603 /
  0.602 / 0.603 / 0.607, second performance 0.737-0.787. The pause's record is not what holds the onset
  back: a gate with no record holds the pose as well, until the onset's own k-step scores arrive.
- **Lending step 1's trust** to the longer steps (alpha_k at least w x alpha_1; prototypes): on every
  frame, w 1 / 0.7: 0.593 / 0.598 pooled, second performance 0.703 / 0.715, worst step 1.044 (climb_3
  left out) / 1.012; step k lent step ceil(k/2)'s, w 1 / 0.7: 0.596 / 0.599, 1.018 / 1.010. Only where
  the step's own record cannot hold the present movement yet (`recognition.onset_trust` w and
  `onset_travel` c, the library's: outside a recognised movement, and over the first k frames of one,
  the pose having travelled c x the motion scale): w 0.25 / 0.5 / 0.75 / 1 with c 0 / 1 / 2 / 3 give
  0.6009 / 0.6009 / 0.6008 / 0.6006, 0.6006 / 0.6005 / 0.5999 / 0.5994, 0.6003 / 0.5996 / 0.5980 /
  0.5973, 0.6001 / 0.5977 / 0.5949 / 0.5937 pooled, worst step 1.008 / 1.008 / 1.008 / 1.008, 1.009 /
  1.008 / 1.009 / 1.009, 1.009 / 1.009 / 1.011 / 1.011, 1.010 / 1.012 / 1.035 / 1.045; second
  performance 0.707-0.734, cold start 0.1400-0.1403 / 0.2038-0.2045, demonstrator check 0.416 (0.407-0.413
  at w 1, c >= 1), below every baseline on all 15 streams. Where the bound breaks is the take learned
  after the others, where the ungated experts are worse than holding at the longer steps and a lent
  trust lets it through at every onset. Keeping the step's own record and lending only while it has
  fewer than e decayed scores of moving frames (the gate split by c, e 1 / 3 / 6): 0.600-0.602, nothing.
  The prototypes' demonstrator checks (0.364-0.408) were void: a deep copy of a model whose `step` was
  replaced on the instance ran the original's parts; the library's setting measures 0.416.
- Rule as before. The lowest pooled within the bound: w 0.5, c 3 (0.5994, worst 1.009); within 0.001 of
  it, the best cold start: w 0.75 with c 0 or 1 (0.1401 / 0.2045 against 0.1402 / 0.2044 summed
  0.34461 / 0.34466), of which c 1 has the lower pooled ratio. Chosen (the default:
  `recognition.onset_trust` 0.75, `recognition.onset_travel` 1): 0.5996 pooled (round 8 0.6012),
  curve 1.000 / 0.729 / 0.549, cold start 0.1401 / 0.2045, worst step 1.009 x hold, check 0.416,
  below every baseline on 15 of 15 streams. A small gain: the onset still waits for step 6's scores
  wherever the longer steps' records are weak, which is what the bound on the take learned after the
  others asks for.
- With it, the ungated weighting's record (`recognition.decay`, round 5's 0.98) swept again: 0.97 /
  0.99 / 0.995 give 0.5995 / 0.6000 / 0.6013 pooled (0.5996), cold start 0.1405 / 0.2056, 0.1397 /
  0.2032, 0.1393 / 0.2028 (0.1401 / 0.2045), worst step 1.009 / 1.009 / 1.010, demonstrator check
  0.413 / 0.424 / 0.427 (0.416); the weighting's own `experts.decay` 0.99 0.5996; `recognition.radius`
  2.5 0.6048. The rule's tie-break would take 0.99 for a cold start better by 0.0004 / 0.0013 rad at
  1.8 % more squared error on the demonstrator check and no pooled gain: not changed (open).

Round 10 (`r10_round9` is round 9's default): what the ungated weighting's record holds. Round 9's
default: 0.5996 pooled, curve 1.000 / 0.729 / 0.549, cold start 0.1401 / 0.2045, worst step 1.009,
check 0.416. Its record scores every prediction alike, those of the first performance too, where every
member was new to the movement; round 5 shortened it (0.98) to forget them, which leaves it short
where the movement is known (round 9: 0.995 loses 0.002 pooled).
- A record of the predictions made where the motion is recognised only (prototypes): decay 0.98 /
  0.99 / 0.995 / 0.999 give 0.6017 / 0.6012 / 0.6011 / 0.6010 pooled, cold start 0.1356 / 0.2053 -
  0.1360 / 0.2033, check 0.406-0.412, but the second performance 0.740 (0.729) and 1.017 x hold at the
  longest step on the real climb_1 learned once (its experts ungated 1.24 x there): at the onset of a
  second performance the record holds only the recognised pause before it. Of a recognised movement only
  (the pose travelled `onset_travel` x the motion scale): 0.6012 / 0.6008 at 0.98 / 0.995, 1.017 x. With
  the last gates at one standard error (`gate.confidence` 1 / 0.75): 0.6036 / 0.6026, worst 1.006, second
  performance 0.755 / 0.747.
- **Predictions outside weighed down** (`recognition.outside_weight` w: a prediction made outside a
  recognised movement counts w, so the first performance still gives the second a weighting, and the
  recognised ones soon outweigh it). Recognised frames: w 0.3 / 0.1 / 0.03 at decay 0.98 give 0.5976 /
  0.5978 / 0.5992 pooled; at 0.995, w 0.2 / 0.1 / 0.05: 0.5961 / 0.5962 / 0.5968; w 0.1 at 0.99 / 0.998:
  0.5968 / 0.5957 (1.015 x on climb_3 left out). Recognised movement (the library's): w 0.1 at 0.995
  0.5959, worst step 1.008, second performance 0.717, cold start 0.1360 / 0.2036, check 0.403; with
  `onset_trust` 0.5 / 1 0.5970 / 0.5942 (1.020 x).
- Rule as before: the lowest pooled within the bound is the library's point (0.5959); within 0.001 of it
  the best cold start is the same point (0.33965 summed). Chosen (the default:
  `recognition.outside_weight` 0.1 over recognised movement, `recognition.decay` 0.995): 0.596 pooled,
  curve 1.000 / 0.717 / 0.538, cold start 0.1360 / 0.2036 (round 9 0.1401 / 0.2045), worst step 1.008,
  demonstrator check 0.403 (0.416): better on every tuning figure. Round 9's open tie-break on
  `recognition.decay` is moot: the record's length is chosen with what it holds.
- The same for the ungated weighting's last gate, which scores it only where it is returned (a
  prototype on the chosen default): scoring it on every frame, those outside weighing w 0 / 0.1 / 0.3 /
  1, gives 0.5960 / 0.5991 / 0.6028 / 0.6105 pooled, second performance 0.718 / 0.740 / 0.766 / 0.803,
  check 0.407-0.432; w 0.1 outside recognised movement 0.5990; w 0.3 without lending 0.6058. The
  ungated weighting is worse than holding on most first performances, and that record shuts its gate
  at the second: not kept.
- With the chosen record, `recognition.radius` 2.5 / 3.5 / 4 give 0.6011 / 0.5960 / 0.5977 pooled,
  worst step 1.009 / 1.030 / 1.029 (climb_3 left out), demonstrator check 0.381 / 0.403 / 0.403; the
  walking streams gain nothing at 4 (0.505 / 0.522 / 0.525 against 0.496 / 0.521 / 0.503); `onset_trust`
  0.6 0.5965. Kept: radius 3, onset_trust 0.75.
- On the recognised movements' record, the ungated weighting's own power (`recognition.power`; it
  had the experts' 4, which the gated weighting keeps): 1 / 2 / 2.5 / 3 / 8 / 16 give 0.5967 / 0.5950 /
  0.5949 / 0.5950 / 0.6019 / 0.6113 pooled, worst step 1.016 / 1.012 / 1.011 / 1.009 / 1.008 / 1.008
  (climb_3 left out below 3), second performance 0.711 / 0.709 / 0.710 / 0.712 / 0.737 / 0.756, cold
  start 0.1359 / 0.2028, 0.1358 / 0.2030, 0.1358 / 0.2031, 0.1359 / 0.2033, 0.1372 / 0.2050, 0.1393 /
  0.2077, demonstrator check 0.383 / 0.390 / 0.393 / 0.397 / 0.424 / 0.448. Rule: the lowest pooled
  within the bound is power 3 (0.5950); within 0.001 of it, 4 (0.5959) has the worse cold start
  (0.33965 against 0.33920 summed). Chosen (the default: `recognition.power` 3): 0.595 pooled, curve
  1.000 / 0.712 / 0.538, cold start 0.1359 / 0.2033, worst step 1.009, check 0.397. A softer weighting
  averages more members where the record says they are close; below 3 it lets the members that are
  worse than holding on the take learned after the others through.

Round 11 (`r11_round10` is round 10's default): what limits the experts once a movement is known.
Round 10's default: 0.5950 pooled, curve 1.000 / 0.712 / 0.538, cold start 0.1359 / 0.2033, worst
step 1.009, check 0.397; its experts ungated 0.631.
- Diagnosis, from the third performance on (prototypes, not kept): the default is 0.509 x hold there,
  its ungated weighting 0.504, the best fixed combination of its members per stream in hindsight (least
  squares) 0.495, the best member frame by frame 0.414: the weighting is close to what weights can do,
  and the members are what limits. The snippet memory alone is 0.57 there (RLS-AR 0.55): it averages
  the futures of its 3 nearest snippets, which lie around the present performance (another size,
  another speed) and are averaged rather than interpolated. Also tried and lost: one weighting per
  joint (`experts.per_joint`) 0.5954 pooled, second performance 0.718; the ungated weighting returned
  only on a recognised movement, not in a recognised pause, 0.596 (`travel` is 2.5 x the motion scale
  in the pauses: the tracker's noise over 8 frames, so it barely separates them); the default's
  predictions moved by a causal smoother's correction of the newest pose (end-point fits over 3-7
  frames, alpha-beta filters): at best equal at every step (the median of 3 frames already filters).
- **The memory's read-out as locally weighted ridge regression** (`memory.fit_k` neighbours, their
  futures fitted as a linear function of their keys' offsets from the present key, ridge `memory.ridge`
  x the offsets' mean variance, read at offset 0). The memory alone: 0.641 -> 0.609 pooled with 32
  neighbours and ridge 1; the mean of the same 32 0.715: the fit wins, not the number of neighbours.
  In the default, fitting everywhere: 0.590-0.592 pooled but up to 1.011-1.012 x hold (real climb_1 /
  climb_2 learned once, the jump streams), where a line fitted far from every neighbour extrapolates;
  and the memory, which read out only once it held `k` snippets, lost the second performance at 40-64
  (0.75-0.88). So the library's fit takes the neighbours there are and runs only where the motion is
  familiar (`familiarity` at most `memory.fit_radius`); elsewhere the 3 nearest are averaged, as before.
- With that, at ridge 0.5: `fit_k` 16 / 24 / 32 / 40 / 48 give 0.5930 / 0.5912 / 0.5904 / 0.5909 /
  0.5916 pooled, worst step 1.0115 / 1.0078 / 1.0100 / 1.0111 / 1.0114; at 32, ridge 0.25 / 0.35 / 0.75
  / 1: 0.5912 / 0.5906 / 0.5909 / 0.5916, worst 1.0098 / 1.0099 / 1.0101 / 1.0101; at 24, ridge 0.25 /
  0.35 / 1: 0.5925 / 0.5917 / 0.5917, worst 1.0093 / 1.0084 / 1.0081; at 32 / 0.5, `fit_radius` 2 / 4:
  0.5921 / 0.5903, worst 1.0100 / 1.0102. With the chosen fit: `memory.velocity_weight` 0.35 / 0.6
  0.5884 / 0.5944, worst 1.019 / 1.012; `memory.insert_scale` 0.25 / 1 0.5906 / 0.5927.
- Rule as before (the lowest pooled ratio at most 1.01 x hold at every step, then the best cold start
  among points within 0.001 of it): `fit_k` 32, ridge 0.35 (0.5906, worst 1.0099); within 0.001, 24 /
  0.5 and 32 / 0.25 (0.5912 each) have cold starts summing 0.3357 / 0.3365 against 0.3356. Chosen (the
  default: `memory.fit_k` 32, `memory.ridge` 0.35, `memory.fit_radius` 3): 0.591 pooled, curve 1.000 /
  0.702 / 0.532, cold start 0.1349 / 0.2007, worst step 1.010, check 0.392; below every baseline,
  its own ungated experts with the same memory (0.625) among them, on 15 of 15 streams (round 10's
  default was behind them on 3). The fit costs speed: 610 frames/s, 0.147 x the recursive hierarchy in
  the bench's run, against 669 and 0.180 for round 10's default in the run after it.
- With the fit, earlier rounds' settings swept again (one run each): `recognition.outside_weight` 0.05 /
  0.2 give 0.5911 / 0.5904 pooled (worst step 1.0093 / 1.0104), `recognition.power` 2 / 4 0.5908 /
  0.5912 (1.0113 / 1.0092), `recognition.radius` 2.5 / 3.5 0.5960 / 0.5905 (1.0131 / 1.0205),
  `experts.power` 3 / 6 0.5906 / 0.5907 (1.0097 / 1.0105), `recognition.onset_trust` 0.5 / 1 0.5914 /
  0.5889 (1.0097 / 1.0107), `gate.confidence` 0.25 / 0.75 0.5900 / 0.5913 (1.0171 / 1.0063),
  `memory.longest_lag` 4 / 16 0.5973 / 0.5991, `memory.k` (averaged where the motion is new) 2 / 5
  0.5904 / 0.5903 (cold start summed 0.3356 / 0.3357, the default 0.3356): within the bound nothing gains
  0.001; kept.
Round 12 (`r12_round11` is round 11's default): a second snippet memory, one expert more.
Round 11's default: 0.5906 pooled, curve 1.000 / 0.702 / 0.532, cold start 0.1349 / 0.2007, worst step
1.0099, check 0.392; below every baseline on 15 of 15.
- Round 11 found the members, not their weighting, to be the limit, and one memory's key lags (4 or 16
  instead of 8) lost. A fifth member, a second memory with another key beside the first (prototypes, then
  `long_memory.*`): longest lag 16 (velocity weight 0.5) 0.5885 pooled, cold start 0.1338 / 0.1980,
  check 0.381, worst step 1.0108 (real climb_2 learned once); longest lag 32 0.5922; the same lags as
  the first with velocity weight 0 / 0.25 / 1: 0.5899 / 0.5878 / 0.5914. So two spans of the past,
  not two copies of one memory, gain. Every point is a `D:` name with the long memory's settings (these at
  `long_memory.fit_radius=3`, e.g. `D:long_memory.longest_lag=32,long_memory.velocity_weight=0.5,
  long_memory.fit_radius=3` without the spaces).
- Longest lag 16 with velocity weight 0.1 / 0.15 / 0.25 / 0.35: 0.5876 / 0.5862 / 0.5861 / 0.5867
  pooled, worst step 1.0089 / 1.0098 / 1.0106 / 1.0104. At 0.15: `fit_radius` 1.5 / 2 / 2.5 / 5 give
  0.5875 / 0.5866 / 0.5865 / 0.5871 (worst 1.0081 / 1.0095 / 1.0097 / 1.0099); `fit_k` 16 / 64
  0.5881 / 0.5864 (1.0105 / 1.0104); `insert_scale` 1 0.5881; fit_radius 2 with velocity weight 0.25 /
  0.1 0.5867 / 0.5879 (1.01002 / 1.0089). The first memory's velocity weight 0.75 beside it: 0.5951
  (its check 0.362, the best of the round, but the rule ranks the repetition streams).
- Rule as before: the lowest pooled ratio within the bound is 0.5862 (longest lag 16, velocity weight
  0.15, fit_radius 3); within 0.001 of it, fit_radius 2 and 2.5 (0.5866 / 0.5865) have cold starts summing
  0.3330 / 0.3334 against 0.3337. Chosen (the default: `long_memory.longest_lag` 16,
  `long_memory.velocity_weight` 0.15, `long_memory.fit_radius` 2, the rest as the first memory's):
  0.5866 pooled, curve 1.000 / 0.702 / 0.528, cold start 0.1344 / 0.1986, worst step 1.0095, check
  0.381. Its own ungated experts, with the same five members, are 0.621; the default is below every
  baseline on 14 of 15 streams, behind them on climb_3 s101 by 0.0008 (0.7005 against 0.6996).
- Beside the chosen two (prototypes, not kept): a third memory with lags up to 4 / 32 (velocity weight
  0.1, fit_radius 2) / 8 at velocity weight 0 / 2 at velocity weight 1 gives 0.5872 / 0.5884 / 0.5876 /
  0.5882 pooled: no gain. Recognising by the long memory's familiarity instead of the first's, or by
  both, or by either: 0.5861 / 0.5861 / 0.5869, but 1.027 / 1.016 / 1.026 x holding at worst (a
  climbing take learned after the others, climb_0 learned once). The ungated weighting's last gate
  with a lower bound of 0 / 0.25 (`gate.confidence` for it alone): 0.5855 / 0.5856, second performance
  0.693 / 0.694, but 1.0195 / 1.0139 x on the jump streams; with a ~10-frame memory (decay 0.9) 0.5926.
- With the long memory, round 11's near misses swept again: `recognition.onset_trust` 1 0.5851 pooled
  (worst 1.0184, a climbing take learned after the others), `gate.confidence` 0.25 0.5855 (1.0139, the
  jump streams), `recognition.outside_weight` 0.2 0.5865 (1.0100; cold start summed 0.3332 against
  0.3330), `experts.power` 3 0.5866 (0.3339): within the bound nothing gains 0.001; kept.

Round 13 (round 12's default, searching by one matrix-vector product: the same figures to 1e-12): what
is left of the second performance's gap. Settings not swept since the fifth member came:
`experts.decay` 0.99 / 0.998 0.5866 / 0.5866 pooled (cold start summed 0.3336 / 0.3329 against
0.3330); `long_memory.ridge` 0.2 / 0.6 0.5863 / 0.5874; `long_memory.k` 5 0.5868; `memory.fit_radius`
4 0.5866; worst step 1.0095-1.0097 for all: nothing gains 0.001, kept. Where the default's second
performance loses to its ungated twin (0.702 against 0.670 on these streams): 89 % of its frames are
recognised, and there the ungated weighting alone is at 0.1227 rad MAE at 600 ms, the default at 0.1302
(hold 0.1938): its last gate opens over the first ~20 frames of the performance (mean alpha at 600 ms
0.16 over frames 0-9, 0.53 over 10-19, 0.94 over 20-29, 1.00 from 30 on, frames counted from the pause
before it). The memory's familiarity does not tell these frames from the jump streams' recognised
ones (both spread over 1-3 x the motion scale; the ungated weighting's MSE 0.36-0.43 x hold's there,
0.99-1.01 x on the jumps), so a trust graded by familiarity was not tried. Shrinking the ungated
weighting towards the gated one instead of the pose, with the same alphas, gains 1-2 % on those frames
(an upper bound: the gate's record would then measure a smaller difference): not built.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

import research  # noqa: F401  (registers the research predictors)
from gwr_predictor.default_predictor import make_gated_network
from gwr_predictor.evaluation.metrics import HorizonStats, future_windows, horizon_stats
from gwr_predictor.evaluation.online import compare_online
from research import candidates as cand
from research import safety
from research.experiments import common
from research.recording import Recorded
from research.repetitions import RepetitionStream, Segment, StreamSettings, load_segments, make_streams
from research.safety import R3
from research.safety import TUNED_NETWORK as TUNED

SEGMENTS: tuple[Segment, ...] = (
    Segment("climb_1", 12.9, 15.9, "climbing move, take 1"),
    Segment("climb_3", 11.3, 14.3, "climbing move, take 3"),
    Segment("omomo_sub3", 0.0, 3.0, "box lift, the other person"),
    Segment("cmu_walk", 11.9, 14.9, "walking, later strides than the benchmark's"),
    Segment("kneel", 11.7, 14.2, "getting up, after the benchmark's cut"),
)
SEEDS = (100, 101, 102)
COLD_PATTERNS = ("raise_lateral_both", "wave_both")
DEMO_PATTERNS = ("wave_one", "raise_front_both", "raise_lateral_both")
DEMO_SEED = 7  # the demonstrator's tuning recordings (`experiment tune` uses them too)
BASELINES = ("hold", "rls_ar", common.LINEAR, common.LLM, common.BLEND_FLAT, common.BLEND, common.GATED,
             common.EXPERTS_UNGATED, common.DEFAULT)
Factory = Callable[[Any, int], Any]
#: Round 3's default: its member gates (`R3`) and the network's settings before `experiment tune` moved
#: to the tuning recordings (the memory's copy rule came later: its figures on the jump streams differ).
ROUND3 = {**R3, "network.rate": 0.1, "network.recruit_surprise": 9.0}
LIN3 = ("llm", "linear", "rls")
#: Rounds 5, 6 and 7's defaults in today's terms: `research.safety`.
R5, R6, R7, R8, R9, R10, R11 = safety.R5, safety.R6, safety.R7, safety.R8, safety.R9, safety.R10, safety.R11
#: Round 5's steps before the last gate's memory was shortened (0.99): the radius sweep with the ungated
#: weighting's record at the weighting's decay (`R5A`), then the decay sweep at radius 3 (`R5B`).
R5A = {**R5, "gate.decay": 0.99, "gate.fast_step": 1, "recognition.decay": 0.995}
R5B = {"gate.decay": 0.99, "gate.fast_step": 1, **R5}

#: grid points measured beside the registered candidates: name -> factory(params, seed)
VARIANTS: dict[str, Factory] = {
    "v_long_d100": lambda p, s: cand.gate(cand.long_model(p, s, global_delta=100.0), p),
    "v_long_g6": lambda p, s: cand.gate(cand.long_model(p, s, global_frames=6), p),
    "v_long_ungated": lambda p, s: cand.long_model(p, s),
    "v_long_c1": lambda p, s: cand.gate(cand.long_model(p, s), p, confidence=1.0),
    "v_long_p001": lambda p, s: cand.gate(cand.long_model(p, s), p, prior=0.001),
    "v_long_c0": lambda p, s: cand.gate(cand.long_model(p, s), p, prior=0.001, confidence=0.5),
    "v_long_fd": lambda p, s: cand.gate(cand.long_model(p, s), p, decay=0.97, prior=0.001, confidence=1.0),
    "v_long_mix99": lambda p, s: cand.gate(cand.long_model(p, s, mix_decay=0.99), p, **cand.FAST_GATE),
    "v_long_ridge": lambda p, s: cand.gate(cand.long_model(p, s, mix_ridge=0.001), p, **cand.FAST_GATE),
    "v_experts_fast": lambda p, s: cand.gate(cand.experts(p, s), p, **cand.FAST_GATE),
    "v_experts_d95": lambda p, s: cand.gate(cand.experts(p, s, decay=0.95), p, **cand.FAST_GATE),
    "v_experts_ungated": lambda p, s: cand.experts(p, s),
    "v_experts2_fast": lambda p, s: cand.gate(cand.experts(p, s, members=("llm", "linear")), p, **cand.FAST_GATE),
    # round 2: choose instead of average, per-expert gates, the network's track record
    "c_choose": lambda p, s: cand.gate(cand.choose(p, s), p, **cand.EXPERTS_GATE),
    "c_choose_dg": lambda p, s: cand.gate(cand.choose(p, s), p),
    "c_choose_ug": lambda p, s: cand.choose(p, s),
    "c_below": lambda p, s: cand.gate(cand.choose(p, s, blend_below="hold"), p, **cand.EXPERTS_GATE),
    "c_below_ug": lambda p, s: cand.choose(p, s, blend_below="hold"),
    "c_pg_blend": lambda p, s: cand.experts_gated(p, s, {}),
    "c_pg_choose": lambda p, s: cand.choose(p, s, names=("llm", "linear", "rls", "hold"), member_gate={}),
    "c_pgf_choose": lambda p, s: cand.choose(p, s, member_gate=cand.EXPERTS_GATE),
    "c_pgf_blend_g": lambda p, s: cand.gate(cand.experts_gated(p, s, cand.EXPERTS_GATE), p),
    "c_pg_blend_g": lambda p, s: cand.gate(cand.experts_gated(p, s, {}), p),
    "c_track": lambda p, s: cand.gate(cand.choose(p, s, track="llm"), p, **cand.EXPERTS_GATE),
    "c_track_below": lambda p, s: cand.gate(cand.choose(p, s, track="llm", blend_below="hold"), p,
                                            **cand.EXPERTS_GATE),
    "c_fav_choose": lambda p, s: cand.gate(cand.choose(p, s, favour={"llm": 0.7}), p, **cand.EXPERTS_GATE),
    "c_g_d95": lambda p, s: cand.gate(cand.experts_gated(p, s, cand.EXPERTS_GATE, decay=0.95), p),
    "c_g_ug": lambda p, s: cand.experts_gated(p, s, cand.EXPERTS_GATE),
    "c_g_fast": lambda p, s: cand.gate(cand.experts_gated(p, s, cand.EXPERTS_GATE), p, **cand.FAST_GATE),
    "c_g_p001": lambda p, s: cand.gate(cand.experts_gated(p, s, cand.EXPERTS_GATE), p, prior=0.001),
    "c_g_pw2": lambda p, s: cand.gate(cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE, average=True,
                                                  power=2.0), p),
    "c_g_track": lambda p, s: cand.gate(cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE, average=True,
                                                    track="llm"), p),
    "c_g_fav": lambda p, s: cand.gate(cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE, average=True,
                                                  favour={"llm": 0.5}), p),
    "c_g_mg_fast": lambda p, s: cand.gate(cand.experts_gated(p, s, cand.FAST_GATE), p),
    "c_g_mg_d97": lambda p, s: cand.gate(cand.experts_gated(p, s, {**cand.FAST_GATE, "decay": 0.97}), p),
    "c_g_mg_c0": lambda p, s: cand.gate(cand.experts_gated(p, s, {"decay": 0.95, "prior": 0.001,
                                                                  "confidence": 0.5}), p),
    "c_g_mg_d90": lambda p, s: cand.gate(cand.experts_gated(p, s, {**cand.EXPERTS_GATE, "decay": 0.9}), p),
    "c_g_ug_d90": lambda p, s: cand.experts_gated(p, s, {**cand.EXPERTS_GATE, "decay": 0.9}),
    "c_g_ug_track": lambda p, s: cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE, average=True,
                                             track="llm"),
    "c_g_ug_fav": lambda p, s: cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE, average=True,
                                           favour={"llm": 0.7}),
    "c_g_ug_pw2": lambda p, s: cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE, average=True,
                                           power=2.0),
    "c_g_fast_d90": lambda p, s: cand.gate(cand.experts_gated(p, s, {**cand.EXPERTS_GATE, "decay": 0.9}), p,
                                           **cand.FAST_GATE),
    "c_g_fast_pw2": lambda p, s: cand.gate(cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE,
                                                       average=True, power=2.0), p, **cand.FAST_GATE),
    "c_g_fast_pw4": lambda p, s: cand.gate(cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE,
                                                       average=True, power=4.0), p, **cand.FAST_GATE),
    "c_g_fast_pw8": lambda p, s: cand.gate(cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE,
                                                       average=True, power=8.0), p, **cand.FAST_GATE),
    "c_g_fast_pw16": lambda p, s: cand.gate(cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE,
                                                        average=True, power=16.0), p, **cand.FAST_GATE),
    "c_g_fast_pw4f": lambda p, s: cand.gate(cand.choose(p, s, names=LIN3, member_gate=cand.EXPERTS_GATE,
                                                        average=True, power=4.0, favour={"llm": 0.7}), p,
                                            **cand.FAST_GATE),
    "v_default_fast": lambda p, s: cand.gate(cand.long_model(p, s, global_frames=2, global_delta=100.0), p,
                                             **cand.FAST_GATE),
    # round 3: the default's experts (`gwr_experts` itself is a registry name)
    "r3_memory_alone": lambda p, s: _memory(p, velocity_weight=1.0, longest_lag=4),
    "r3_memory_v1": lambda p, s: safety.default(p, s, {**ROUND3, "memory.velocity_weight": 1.0}),
    "r3_loose_members": lambda p, s: safety.default(p, s, {**ROUND3, "expert_gate.confidence": 0.5}),
    "r3_no_last_gate": lambda p, s: safety.experts_of(safety.default(p, s, ROUND3)),
    "r3_power16": lambda p, s: safety.default(p, s, {**ROUND3, "experts.power": 16.0, "experts.decay": 0.99}),
    "r3_last_gate_z0": lambda p, s: safety.default(p, s, {**ROUND3, "gate.confidence": 0.0}),
    "r3_default": lambda p, s: safety.default(p, s, ROUND3),
    # round 4 (`research.safety`; on round 3's member gates, `R3`, unless named `r4_warm*`)
    "r4_r3": lambda p, s: safety.default(p, s, R3),
    "r4_no_last_gate": lambda p, s: safety.rebuilt(p, s, R3, last_gate=False),
    "r4_ug_hold_last": lambda p, s: safety.rebuilt(p, s, R3, member_gates=False, hold=True),
    "r4_ug_hold": lambda p, s: safety.rebuilt(p, s, R3, member_gates=False, hold=True, last_gate=False),
    "r4_g_hold_last": lambda p, s: safety.rebuilt(p, s, R3, hold=True),
    "r4_gate_lin": lambda p, s: safety.rebuilt(p, s, R3, member_gates=("linear", "rls_ar")),
    "r4_gate_lin_nolast": lambda p, s: safety.rebuilt(p, s, R3, member_gates=("linear", "rls_ar"), last_gate=False),
    "r4_mem_ungated": lambda p, s: safety.rebuilt(p, s, R3, member_gates=("linear", "rls_ar", "network")),
    "r4_last_d95_z0": lambda p, s: safety.default(p, s, {**R3, "gate.decay": 0.95, "gate.confidence": 0.0}),
    "r4_mg_d90": lambda p, s: safety.default(p, s, {**R3, "expert_gate.decay": 0.9}),
    "r4_mg_d98": lambda p, s: safety.default(p, s, {**R3, "expert_gate.decay": 0.98}),
    "r4_mg_d99": lambda p, s: safety.default(p, s, {**R3, "expert_gate.decay": 0.99}),
    "r4_allgate": lambda p, s: safety.rebuilt(p, s, R3, own_gate=("network", "memory", "linear", "rls_ar")),
    "r4_two_gates": lambda p, s: safety.two_gates(p, s, {"decay": 0.99, "prior": 0.001, "confidence": 1.0}, R3),
    "r4_agree": lambda p, s: safety.agreeing(p, s, 1.0, R3, weighted=False),
    "r4_agree_last": lambda p, s: safety.agreeing(p, s, 1.0, R3, weighted=False, last_gate=True),
    "r4_agree_mg": lambda p, s: safety.agreeing(p, s, 1.0, R3, member_gates=True),
    "r4_pw8": lambda p, s: safety.default(p, s, {**R3, "experts.power": 8.0}),
    "r4_d999": lambda p, s: safety.default(p, s, {**R3, "experts.decay": 0.999}),
    "r4_warm200_99": lambda p, s: safety.default(p, s, {**TUNED, "expert_gate.decay": 0.99, "expert_gate.warmup": 200}),
    "r4_warm400_99": lambda p, s: safety.default(p, s, {**TUNED, "expert_gate.decay": 0.99}),
    "r4_warm800_99": lambda p, s: safety.default(p, s, {**TUNED, "expert_gate.decay": 0.99, "expert_gate.warmup": 800}),
    "r4_warm400_93": lambda p, s: safety.default(p, s, {**TUNED, "expert_gate.warmup_decay": 0.93}),
    "r4_warm400_995": lambda p, s: safety.default(p, s, TUNED),
    # round 5: the memory's recognition lifts the member gates (`recognition.py`), radius 1.5-6
    "r5_radius15": lambda p, s: safety.default(p, s, {**R5A, "recognition.radius": 1.5}),
    "r5_radius2": lambda p, s: safety.default(p, s, {**R5A, "recognition.radius": 2.0}),
    "r5_radius3": lambda p, s: safety.default(p, s, {**R5A, "recognition.radius": 3.0}),
    "r5_radius4": lambda p, s: safety.default(p, s, {**R5A, "recognition.radius": 4.0}),
    "r5_radius6": lambda p, s: safety.default(p, s, {**R5A, "recognition.radius": 6.0}),
    "r5_round4": lambda p, s: safety.default(p, s, safety.BEFORE_ROUND5),
    "r6_round5": lambda p, s: safety.default(p, s, R5),
    "r7_round6": lambda p, s: safety.default(p, s, R6),
    "r8_round7": lambda p, s: safety.default(p, s, R7),
    "r9_round8": lambda p, s: safety.default(p, s, R8),
    "r10_round9": lambda p, s: safety.default(p, s, R9),
    "r11_round10": lambda p, s: safety.default(p, s, R10),
    "r12_round11": lambda p, s: safety.default(p, s, R11),
    "r5_blend95": lambda p, s: safety.blended(p, s, 0.95, settings=R5A),
    "r5_blend99": lambda p, s: safety.blended(p, s, 0.99, settings=R5A),
    "r5_blend95_98": lambda p, s: safety.blended(p, s, 0.95, settings=R5B),
    "r5_blend99_98": lambda p, s: safety.blended(p, s, 0.99, settings=R5B),
    "r5_blend95_98_pw16": lambda p, s: safety.blended(p, s, 0.95, power=16.0, settings=R5B),
    "r5_ungated_d95": lambda p, s: safety.default(p, s, {**R5B, "recognition.decay": 0.95}),
    "r5_ungated_d98": lambda p, s: safety.default(p, s, {**R5B, "recognition.decay": 0.98}),
    "r5_ungated_d995": lambda p, s: safety.default(p, s, {**R5B, "recognition.decay": 0.995}),
}


def _memory(params: Any, **changes: Any) -> Any:
    from gwr_predictor.default_predictor import MemoryParams, TrajectoryMemory

    return TrajectoryMemory(MemoryParams(horizon=params.horizon, n_joints=params.n_joints, **changes))


def factory(name: str) -> Factory:
    """A registry name, a `VARIANTS` key, `D:<setting>=<value>,...` (the default with those flat
    settings, e.g. `D:expert_gate.fast_decay=0.8`), `U:<setting>=<value>,...` (its experts with those,
    without any gate: the default's own ungated model), `G:<setting>=<value>,...` (the gated network with
    those), or `X<blend decay>[^<power>]_<gate key=value,...>`: the experts with that blend decay (and
    weight power) behind a gate with those settings (e.g. `X0.99_decay=0.95,prior=0.001,confidence=1`,
    the chosen `cand_experts`)."""
    if name in VARIANTS:
        return VARIANTS[name]
    if name.startswith("D:"):
        return lambda p, s: safety.default(p, s, _settings(name[2:]))
    if name.startswith("U:"):
        return lambda p, s: safety.ungated(p, s, _settings(name[2:]))
    if name.startswith("G:"):
        return lambda p, s: make_gated_network(p.horizon, p.n_joints, s, _settings(name[2:]))
    if name.startswith("X") and "_" in name:
        blend, _, spec = name[1:].partition("_")
        decay, _, power = blend.partition("^")
        changes = {k: float(v) for k, v in (kv.split("=") for kv in spec.split(",") if kv)}
        return lambda p, s: cand.gate(cand.experts(p, s, decay=float(decay), power=float(power or 1.0)), p,
                                      **changes)
    return lambda p, s, n=name: common.make_model(n, p, s)


#: The `D:` settings that are integers.
INTEGER_SETTINGS = ("warmup", "fast_step", "k", "fit_k", "future", "longest_lag", "order", "global_order", "readout_k")


def _settings(spec: str) -> dict[str, Any]:
    """`key=value,...` as flat settings (true/false as bools, the `INTEGER_SETTINGS` as ints, other numbers as
    floats)."""
    out: dict[str, Any] = {}
    for key, _, value in (kv.partition("=") for kv in spec.split(",") if kv):
        if value in ("true", "false"):
            out[key] = value == "true"
        else:
            out[key] = int(value) if key.rsplit(".", 1)[-1] in INTEGER_SETTINGS else float(value)
    return out


def tuning_streams() -> list[RepetitionStream]:
    return make_streams(load_segments(SEGMENTS), SEEDS, StreamSettings())


def score_stream(stream: RepetitionStream, methods: tuple[str, ...], seed: int = 0) -> dict[str, Any]:
    """One pass from scratch per method: MAE per step, and at the last step per performance."""
    params = common.make_params()
    h, joints = params.horizon, params.n_joints
    models = {m: Recorded(factory(m)(params, seed)) for m in methods}
    res = compare_online(models, [stream.angles], horizon=h, progress=False)
    preds = {m: r.predictions(h, joints) for m, r in models.items()}
    scored = np.logical_and.reduce([np.isfinite(p).all(axis=(1, 2)) for p in preds.values()])
    future = future_windows(stream.angles, h)
    reps = [scored & (stream.repetition == k) for k in range(int(stream.repetition.max()) + 1)]
    return {"name": stream.name,
            "stats": {m: r.stats for m, r in res.items()},
            "per_rep": {m: [horizon_stats(p[sel], future[sel]) for sel in reps] for m, p in preds.items()}}


def _jumps(n: int, seed: int, chance: float = 0.05) -> np.ndarray:
    """The sudden-jump stream of test/test_default_predictor.py (nothing repeats)."""
    rng = np.random.default_rng(seed)
    moves = rng.random((n, 1)) < chance
    return 0.3 + np.cumsum(moves * rng.normal(scale=0.3, size=(n, 8)), axis=0)


def _one_pass(methods: tuple[str, ...], sequences: list[Any]) -> dict[str, HorizonStats]:
    params = common.make_params()
    models = {m: factory(m)(params, 0) for m in methods}
    return {m: r.stats for m, r in compare_online(models, sequences, horizon=params.horizon, progress=False).items()}


def _left_out(methods: tuple[str, ...], held: dict[str, Any], others: list[np.ndarray]) -> dict[str, HorizonStats]:
    """The real clips' leave-one-take-out condition (`experiment real`): the other takes learned online
    once, then the held-out take, learning on."""
    from gwr_predictor.evaluation.online import train_online

    params = common.make_params()
    models = {m: factory(m)(params, 0) for m in methods}
    for model in models.values():
        train_online(model, others, passes=1, progress=False)
    return {m: r.stats for m, r in compare_online(models, [held["angles"]], horizon=params.horizon,
                                                  progress=False).items()}


def _demo_heldout(methods: tuple[str, ...]) -> dict[str, float]:
    """The demonstrator check (`--demo`): per pattern, 5 epochs over 3 repetitions of 2 people, then the
    unseen repetitions frozen; MSE at the last step as a share of holding the pose (seed 7's recordings)."""
    from gwr_predictor.predictors import registry
    from research.experiments import dataloss

    names = {m: re.sub(r"\W", "_", m) for m in methods}  # registry names are identifiers
    for m, n in names.items():
        if n not in registry.names():
            registry.register(n, lambda p, s, m=m: factory(m)(p, s), m)
    cfg = dataloss.Config(losses=(0.0,), patterns=DEMO_PATTERNS, subjects=2, train_repetitions=3, epochs=5,
                          methods=tuple(names.values()))
    data = common.demo_data(cfg.patterns, cfg.subjects, cfg.train_repetitions + cfg.test_repetitions, DEMO_SEED)
    held = dataloss.one_level(cfg, 0.0, data, 0, False)["heldout"]
    return {m: held[n]["mse"][-1] / held["hold"]["mse"][-1] for m, n in names.items()}


def _task(job: tuple[str, Any, tuple[str, ...]]) -> tuple[str, Any]:
    kind, item, methods = job
    if kind == "demo":
        return kind, _demo_heldout(methods)
    if kind == "stream":
        return kind, score_stream(item, methods)
    if kind == "cold":
        return kind, (item, _one_pass(methods, list(common.demo_data((item,), 3, 10, 0))))
    if kind == "jump":
        return kind, (f"jumps s{item}", _one_pass(methods, [_jumps(800, item)]))
    if kind == "left_out":
        held, others = item
        return kind, (held["name"], _left_out(methods, held, others))
    return kind, (item["name"], _one_pass(methods, [item["angles"]]))


def evaluate(methods: tuple[str, ...], real: bool = False, workers: int = 2, demo: bool = False) -> dict[str, Any]:
    """Every tuning figure for `methods` (hold first)."""
    methods = tuple(dict.fromkeys(("hold", *methods)))
    jobs: list[tuple[str, Any, tuple[str, ...]]] = [("demo", None, methods)] if demo else []
    jobs += [("stream", s, methods) for s in tuning_streams()]
    jobs += [("cold", p, methods) for p in COLD_PATTERNS] + [("jump", s, methods) for s in SEEDS]
    if real:
        from research.experiments.real import Config, left_out_takes, load_clips

        clips = load_clips(Config())
        jobs += [("real", c, methods) for c in clips] + [("left_out", t, methods) for t in left_out_takes(clips)]
    with ProcessPoolExecutor(workers) as pool:
        done = list(pool.map(_task, jobs))
    return summarise(methods, done)


def summarise(methods: tuple[str, ...], done: list[tuple[str, Any]]) -> dict[str, Any]:
    streams = [r for k, r in done if k == "stream"]
    last = {s["name"]: {m: s["stats"][m].mae[-1] / s["stats"]["hold"].mae[-1] for m in methods} for s in streams}
    pooled = {m: HorizonStats.empty(6, 8) for m in methods}
    curve = {m: [HorizonStats.empty(6, 8)] * 8 for m in methods}
    for s in streams:
        for m in methods:
            pooled[m] = pooled[m].merge(s["stats"][m])
            curve[m] = [c.merge(r) for c, r in zip(curve[m], s["per_rep"][m], strict=True)]
    worst = {}
    for k, (name, stats) in ((k, r) for k, r in done if k not in ("stream", "demo")):
        worst[f"{k}:{name}"] = {m: float(np.max(np.array(stats[m].mae) / np.array(stats["hold"].mae)))
                                for m in methods}
    cold = {name: {m: float(stats[m].mae[-1]) for m in methods} for k, (name, stats) in
            ((k, r) for k, r in done if k == "cold")}
    return {
        "per_stream": last,
        "pooled": {m: float(pooled[m].mae[-1] / pooled["hold"].mae[-1]) for m in methods},
        "curve": {m: [float(c.mae[-1] / hc.mae[-1]) for c, hc in zip(curve[m], curve["hold"], strict=True)]
                  for m in methods},
        "cold_mae_600": cold,
        "worst_step_ratio": worst,
        "demo_heldout_mse": next((r for k, r in done if k == "demo"), {}),
    }


def report(r: dict[str, Any], candidates: tuple[str, ...]) -> str:
    """Per candidate: pooled ratio, learning curve, streams where it beats every baseline, cold start, worst ratio."""
    base = [m for m in BASELINES if m in r["pooled"] and m != "hold"]
    lines = ["pooled ratio@600: " + ", ".join(f"{m} {r['pooled'][m]:.3f}" for m in r["pooled"])]
    for m in r["pooled"]:
        curve = " ".join(f"{v:.3f}" for v in r["curve"][m])
        cold = " ".join(f"{p} {v[m]:.4f}" for p, v in r["cold_mae_600"].items())
        worst = max(v[m] for v in r["worst_step_ratio"].values())
        where = max(r["worst_step_ratio"], key=lambda k, m=m: r["worst_step_ratio"][k][m])
        line = f"{m:>18}: pooled {r['pooled'][m]:.3f} | curve {curve} | cold {cold} | worst {worst:.3f} ({where})"
        if r["demo_heldout_mse"]:
            line += f" | demo {r['demo_heldout_mse'][m]:.3f}"
        if m in candidates:
            rivals = [b for b in base if b != m]
            wins = sum(all(s[m] < s[b] for b in rivals) for s in r["per_stream"].values())
            margin = max(s[m] - min(s[b] for b in rivals) for s in r["per_stream"].values())
            line += f" | beats all {wins}/{len(r['per_stream'])} streams, worst margin {margin:+.3f}"
        lines.append(line)
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help="registry names or VARIANTS")
    ap.add_argument("--real", action="store_true", help="also the real clips, one pass and each climbing take "
                    "learned after the others (the <= 1.02 bound)")
    ap.add_argument("--demo", action="store_true", help="also the demonstrator check on the tuning recordings")
    ap.add_argument("--out", default=None, help="JSON of the figures")
    args = ap.parse_args(argv)
    names = tuple(args.names) or tuple(cand.CANDIDATES)
    r = evaluate((*BASELINES, *names), real=args.real, demo=args.demo)
    print(report(r, names))
    if args.out:
        with open(args.out, "w") as f:
            json.dump(r, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

