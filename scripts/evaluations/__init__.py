"""The evaluations against OpenCV (and mrcal), one module each, run by the launchers in
scripts/evaluate/ as `python3 -m evaluations.NAME` (with scripts/ on PYTHONPATH).

Shared:
- service: the HTTP the evaluations speak to the service (the one multipart encoder, a POST on
  its own connection or timed on a kept-alive one, NPY answers, the keep rules measured);
- peers: OpenCV's StereoSGBM in its modes, set as the issues set them;
- scoring: Middlebury's bad-x with holes filled, density, the methods' table, the floors;
- scenes: Motorcycle's rig and variants, the rendered slanted scene, Aloe;
- board_truth, raw_pair: a photographed board's plane as truth, and raw pairs rendered through
  distorted rigs.

One file an evaluation (launcher in brackets):
- stereo, sigma, indoor, board, stream (evaluate/matcher): the matcher on Middlebury, σ_d's
  coverage and WLS confidence (wls_confidence runs in the contrib venv), OpenCV's real
  photographs, their boards' planes, a raw 720p stream;
- corners (evaluate/corners): sub-pixel corners against cornerSubPix;
- calibration, charuco, uncertainty (evaluate/calibration): /calibrate against OpenCV's
  calibration, ChArUco against CharucoDetector, the projection uncertainty against mrcal;
- rectify (evaluate/rectification): stereoRectify, the maps and remap;
- by hand: compare_builds (two builds in turns), corner_sizes (OpenCV's corner sizes).
"""
