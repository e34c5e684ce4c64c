"""The reproduction report: only runs that isolated the true faulty parameter show an End of Life."""

from ea_gym.reproduce import PAPER_TABLE_3, PhaseEoL, headline, report_markdown, run_record


def _results(isolated, outcome, favoured):
    return {
        "detection_time": 10.0,
        "isolated_parameter": isolated,
        "isolation": {"state": "isolated" if isolated else "undecided", "favoured": favoured, "confidence": 0.6, "threshold": 0.75},
        "metrics": {"isolation_outcome": outcome, "estimation": None, "eol_phases": []},
    }


def _summary():
    fault, corrective = PhaseEoL(57.3, 55.0, 4.4), PhaseEoL(121.7, 118.5, None)
    runs = {
        "right": run_record(_results("k", "right", "k"), fault, corrective),
        "wrong": run_record(_results("b", "wrong", "b"), fault, corrective),
        "undecided": run_record(_results(None, "undecided", "m"), fault, corrective),
    }
    return {"eol_fault_true": 55.0, "eol_fault": runs["right"]["eol_fault"], "eol_corrective": runs["right"]["eol_corrective"],
            "headline_run": "right", "estimator": "tracking", "eol_corrective_true": 118.5, "paper_table_3": PAPER_TABLE_3, "runs": runs,
            "isolation_training": None, "wall_time_s": 1.0}


def test_run_record_keeps_an_end_of_life_only_from_a_run_isolated_right():
    runs = _summary()["runs"]
    assert (runs["right"]["eol_fault"], runs["right"]["eol_corrective"]) == (57.3, 121.7)
    for name in ("wrong", "undecided"):
        assert runs[name]["eol_fault"] is None and runs[name]["eol_corrective"] is None
        assert runs[name]["eol_fault_max_error_after_30s"] is None
    assert runs["wrong"]["isolation"] == "wrong" and runs["undecided"]["favoured"] == "m"


def test_table_3_marks_wrong_and_undecided_runs_instead_of_their_end_of_life():
    lines = report_markdown(_summary()).splitlines()
    assert any("the `tracking` estimator" in line for line in lines)  # the report names the estimator that ran
    (fault,) = [line for line in lines if line.startswith("| fault |")]
    assert fault.endswith("| 57.3 s | - (isolated b, wrong) | - (undecided, m favoured) |")
    (corrective,) = [line for line in lines if line.startswith("| corrective action |")]
    assert "121.7 s" in corrective and "- (isolated b, wrong)" in corrective
    (wrong,) = [line for line in lines if line.startswith("| [wrong]")]
    assert "| isolated b, wrong |" in wrong and "57.3" not in wrong
    (undecided,) = [line for line in lines if line.startswith("| [undecided]")]
    assert "| undecided, m favoured |" in undecided and "57.3" not in undecided


def test_the_headline_says_why_a_run_has_no_end_of_life():
    summary = _summary()
    assert headline(summary) == (
        "End of Life, fault: 57.3 s (truth 55.0 s, paper 55 s); corrective action: 121.7 s (truth 118.5 s, paper 113 s)"
    )
    summary.update(headline_run="wrong", eol_fault=None, eol_corrective=None)
    assert headline(summary).startswith("End of Life, fault: - (isolated b, wrong) (truth 55.0 s, paper 55 s)")
