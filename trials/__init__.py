"""The `trials` command, the study folder, scenarios, the simulator, the controllers and the runner."""
