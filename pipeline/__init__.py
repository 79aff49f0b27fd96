"""Pure numerical core of loopwatch: oscillation gate, EMD, IMF pruning, instantaneous
frequency, DNL/TDNL and the verdict.  No I/O, no clock, no network in this package."""
