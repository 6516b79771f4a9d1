"""End-to-end workflows shared by demos and tests."""
