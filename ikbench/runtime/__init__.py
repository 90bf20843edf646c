"""Where and how studies run: the harness that times every solve the same way and keeps
failures as rows, the executors (this process, Ray), batched solves split over workers."""
