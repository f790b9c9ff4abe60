"""Experimental designs for field trials: factors, model terms, D-optimal designs, diagnostics, plans."""
