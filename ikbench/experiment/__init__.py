"""The pointing experiment (Lucny et al., ICSR 2025): NICO's arm stopped at a fraction of its
path toward one of the touchscreen targets, under gaze, pointing, congruent and incongruent
cues; participants touch the target they predict.

Data flows one way: design (trial lists) -> play (robot, emulator, simulated participants) ->
responses -> analysis (rates with intervals, mixed-effects model, contrasts, observers' fit).
A trial list is the contract between design and play; the analysis reads only files.
"""
