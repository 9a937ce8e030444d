"""The evaluation harness: corpus, trials, metrics, results and reports (ARCHITECTURE.md section 5)."""
