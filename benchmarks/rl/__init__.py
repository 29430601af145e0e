"""RL training tooling: train (``python -m benchmarks.rl.train``), evaluate, the training runs'
plans, their summary and shipping a model into the package. The benchmark engine loads trained
policies through :class:`gp_agents.rl.RLAgent`; nothing here is imported by it."""
