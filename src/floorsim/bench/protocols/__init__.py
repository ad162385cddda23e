"""Paper protocols the bench runs on the scenes that ask for them."""
