"""Small helpers with no home of their own: a bounded cache, and the message naming a missing extra."""
