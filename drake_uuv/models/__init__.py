"""The paper's model, its filters and its control laws as plain numpy (no Drake systems)."""
