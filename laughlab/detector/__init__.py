"""Real-time laughter detection: features, the model, the gate, and its fitting on the corpus."""
