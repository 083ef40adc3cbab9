"""A lab session's export as a BIDS-Motion dataset."""
