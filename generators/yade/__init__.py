"""YADE drivers: scenes run headless by Debian's `yade -n -x` on generated scripts."""
