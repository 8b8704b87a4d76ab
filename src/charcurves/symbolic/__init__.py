"""Symbolic regression: engines behind one interface, post-SR distillation, SR and SR-CC."""
