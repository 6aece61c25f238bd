"""Quarantine reasons on the data page: the placeholders of reason_category are filled back in."""
import pandas as pd

from wsnloc.metrics.data_quality import quarantine_by_reason, reasons_with_values


def test_reasons_keep_their_numbers():
    reasons = pd.Series(["expected 4 fields 't_ms anchor tw_toa_ps status', found 3"] * 2
                        + ["expected 4 fields 't_ms anchor tw_toa_ps status', found 5",
                           "expected 3 fields (t,v_mps,yaw_rate_rps), found 2",
                           "expected 3 fields (t,v_mps,yaw_rate_rps), found 4",
                           "ID 'zz' is not 8 hex bytes", "ID 'yy' is not 8 hex bytes"])
    texts = reasons_with_values(reasons)
    assert not any(" N " in t or t.endswith(" N") or "found N" in t for t in texts), list(texts)
    assert "expected 3 fields (t,v_mps,yaw_rate_rps), found 2 (and 1 more with other numbers)" in list(texts)
    assert any(t.startswith("ID '…' is not 8 hex bytes (e.g.") for t in texts)


def test_quarantine_by_reason_counts_per_file():
    q = pd.DataFrame({"file": ["a.log", "a.log", "b.csv"],
                      "reason": ["expected 4 fields, found 3", "expected 4 fields, found 5", "bad 'x'"]})
    rows = quarantine_by_reason(q)
    assert ("a.log", "expected 4 fields, found 3 (and 1 more with other numbers)", 2) in rows
    assert ("b.csv", "bad 'x'", 1) in rows
