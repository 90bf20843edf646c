"""The studies that run methods and write results: run, ablation, sweep, bench, batch;
the harness that times every solve, and the reports and figures."""
