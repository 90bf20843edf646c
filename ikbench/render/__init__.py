"""Reports, tables and figures made from written results: run reports, leaderboards,
arm plots, pose-path figures, animations, timing plots."""
