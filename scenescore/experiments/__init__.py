"""The paper's experiments as runnable functions (the CLI's ``scenescore experiment``)."""
