// footscand dashboard: filled in by the dashboard work.
