"""Real recordings: readers for public cable data sets and the validation of the model against them."""
