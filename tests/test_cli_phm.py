"""``ea-gym phm --measurements`` on records of a two-mass machine made by an independent ODE (scipy's solve_ivp, not
ea-gym): data the model cannot explain is said so, with nothing isolated and no End of Life; the commissioning and the
load-noise options reach the chain and results.json."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ea_gym.phm
from ea_gym.cli import main
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.database import classes_of

RATE = 100.0  # Hz
NOISE = 0.01
#: two masses in a chain: F drives m1 (held by k1, b1); k2 and b2 in parallel on the masses' relative motion drive m2
MODEL = """name: two_masses
elements:
  F: {kind: Se, unit: N}
  v1: {kind: "1"}
  m1: {kind: I, value: 8.0, unit: kg, limits: [7.0, 9.0]}
  k1: {kind: C, form: stiffness, value: 120.0, unit: N/m, limits: [100.0, 130.0]}
  b1: {kind: R, value: 0.6, unit: N s/m, limits: [0.45, 0.75]}
  link: {kind: "0"}
  rel: {kind: "1"}
  k2: {kind: C, form: %s, value: 60.0, unit: N/m, limits: [50.0, 66.0]}
  b2: {kind: R, value: 0.4, unit: N s/m}
  v2: {kind: "1"}
  m2: {kind: I, value: 4.0, unit: kg, limits: [3.5, 4.5]}
bonds: [[F, v1], [v1, m1], [v1, k1], [v1, b1], [v1, link], [link, rel], [link, v2], [rel, k2], [rel, b2], [v2, m2]]
load: {source: F, nominal: 10.0, bandwidth: 2.0}
"""
NOMINAL = {"m1": 8.0, "k1": 120.0, "b1": 0.6, "k2": 60.0, "b2": 0.4, "m2": 4.0}


def load_of(t: np.ndarray) -> np.ndarray:
    """A multisine of four tones up to 1.8 Hz around 10 N."""
    frequency, phase = np.array([0.14, 0.46, 1.02, 1.8]), np.array([0.3, 1.9, 4.0, 5.5])
    return 10.0 * (1 + 0.1 * np.sin(2 * np.pi * frequency * np.asarray(t)[..., None] + phase).sum(-1))


def record(duration: float, seed: int, rate: float = RATE, **values: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """t, load and the signals [v1, x1, x12, v2] (m/s, m, m, m/s) at ``rate`` Hz of the machine at ``values`` (else
    NOMINAL), from rest, with NOISE of each signal's RMS per second:
    m1 v1' = F - k1 x1 - b1 v1 - k2 x12 - b2 (v1 - v2), x1' = v1, x12' = v1 - v2, m2 v2' = k2 x12 + b2 (v1 - v2)."""
    p = {**NOMINAL, **values}

    def rhs(s: float, y: np.ndarray) -> list[float]:
        v1, x1, x12, v2 = y
        coupling = p["k2"] * x12 + p["b2"] * (v1 - v2)
        return [(float(load_of(s)) - p["k1"] * x1 - p["b1"] * v1 - coupling) / p["m1"], v1, v1 - v2, coupling / p["m2"]]

    t = np.arange(round(duration * rate) + 1) / rate
    clean = solve_ivp(rhs, (0, t[-1]), np.zeros(4), t_eval=t, method="DOP853", rtol=1e-10, atol=1e-12, max_step=0.5 / rate).y.T
    rng, second = np.random.default_rng(seed), round(rate)
    noisy = clean.copy()
    for start in range(0, len(t), second):
        block = clean[start : start + second]
        noisy[start : start + second] += NOISE * np.sqrt(np.mean(block**2, 0)) * rng.standard_normal(block.shape)
    return t, load_of(t), noisy


def write_csv(path: Path, t: np.ndarray, load: np.ndarray, signals: np.ndarray) -> Path:
    # the model's state order: m1's flow v1, k1's displacement x1, k2's x12, m2's flow v2
    np.savetxt(path, np.column_stack([t, load, signals]), fmt="%.12g", delimiter=",", header="t,F,m1,k1,k2,m2", comments="")
    return path


class _Uniform(FaultClassifier):
    """A stand-in for the model's isolation network (none is shipped for this model; training one takes a minute): every
    class equally likely, whatever the features."""

    def predict_proba(self, features: np.ndarray) -> np.ndarray:
        return np.full((len(features), len(self.classes)), 1.0 / len(self.classes))


@pytest.fixture
def stand_in_network(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ea_gym.phm, "classifier_for", lambda model, path=None: _Uniform(classes_of(model), "strong", 1))


def phm(tmp_path: Path, model: Path, csv: Path, *extra: str, noise: bool = True) -> dict[str, Any]:
    """results.json of ``ea-gym phm`` on the record ``csv`` of ``model`` (with ``--noise NOISE`` where ``noise``)."""
    out = tmp_path / f"out_{csv.stem}"
    given = ["--noise", str(NOISE)] if noise else []
    assert main(["phm", "--system", str(model), "--measurements", str(csv), *given, "--out", str(out), *extra]) == 0
    return json.loads((out / "results.json").read_text())


def model_file(tmp_path: Path, form: str = "stiffness") -> Path:
    path = tmp_path / f"two_masses_{form}.yaml"
    path.write_text(MODEL % form)
    return path


def nothing_said(results: dict[str, Any]) -> bool:
    """No part isolated, none named degrading, no End of Life anywhere."""
    no_rul = all(value is None for series in results["components"].values() for value in series["rul"])
    return results["isolated_parameter"] is None and results["degrading"] == [] and results["eol_predictions"] == [] and no_rul


@pytest.mark.usefixtures("stand_in_network")
@pytest.mark.parametrize("case", ["healthy", "unit", "time_base", "form"])
def test_data_the_model_cannot_explain_is_said_so_and_nothing_else(case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The load column in kN read as N, 200 Hz data whose t column says 100 Hz, k2 written as a compliance: the model does
    not fit, nothing is isolated, no End of Life; the healthy record of the same machine fits."""
    rate = 2 * RATE if case == "time_base" else RATE
    t, load, signals = record(60.0 * RATE / rate, seed=1, rate=rate)
    csv = write_csv(tmp_path / f"{case}.csv", np.arange(len(t)) / RATE, load / 1000 if case == "unit" else load, signals)
    results = phm(tmp_path, model_file(tmp_path, "compliance" if case == "form" else "stiffness"), csv)
    fit = results["model_fit"]
    printed = capsys.readouterr().out
    if case == "healthy":
        assert fit["ok"] is True and fit["statistic"] < 2.0, fit
        return
    assert fit["ok"] is False and fit["statistic"] > fit["band"][1], fit
    assert nothing_said(results), (results["isolated_parameter"], results["degrading"], len(results["eol_predictions"]))
    assert "the model does not fit the data" in printed and "degrading parts: none" in printed


#: a healthy machine off its catalogue values, both parts inside their limits: m1 3.75 % heavier, k1 3.3 % softer
OFF_NOMINAL = {"m1": 8.3, "k1": 116.0}


@pytest.fixture
def commissioned_at_the_truth(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """``ea_gym.phm.commission`` replaced by one that returns the machine's true values (its own fit is the chain's,
    tested there): what the command passes it is logged."""
    calls: list[dict[str, Any]] = []

    def commission(model: Any, measured: np.ndarray, load: np.ndarray, load_rate: np.ndarray, sample_rate: float, noise: float,
                   load_noise: float = 0.0) -> ea_gym.phm.Commissioning:
        calls.append({"measured": measured, "load": load, "load_rate": load_rate, "sample_rate": sample_rate, "noise": noise,
                      "load_noise": load_noise})
        names = classes_of(model)[1:]
        value = np.array([[{**NOMINAL, **OFF_NOMINAL}[name] for name in names]])
        return ea_gym.phm.Commissioning(names, value, np.full(value.shape, 0.01))

    monkeypatch.setattr(ea_gym.phm, "commission", commission)
    return calls


@pytest.mark.usefixtures("stand_in_network")
def test_a_commissioned_machine_is_the_chains_healthy_one(tmp_path: Path, commissioned_at_the_truth: list[dict[str, Any]],
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """Against the catalogue values the off-nominal machine raises an alarm (measured at 7 s, k1 isolated) and its
    residuals read as 1.8 % noise; commissioned on its first 20 s, no alarm, and its noise reads 0.97 % (1 % put in)."""
    t, load, signals = record(60.0, seed=2, **OFF_NOMINAL)
    csv = write_csv(tmp_path / "off.csv", t, load, signals)
    model = model_file(tmp_path)
    catalogue = phm(tmp_path, model, csv)
    assert catalogue["detection_time"] is not None and "commissioning" not in catalogue
    assert catalogue["run"]["noise_estimate"] > 0.015 and catalogue["run"]["load_noise_source"] == "assumed exact"
    (tmp_path / "out_off").rename(tmp_path / "catalogue")
    results = phm(tmp_path, model, csv, "--commission-seconds", "20", "--load-noise", "0.002")
    assert results["detection_time"] is None and results["degrading"] == []
    assert results["commissioning"] == {"values": {"m1": 8.3, "k1": 116.0, "b1": 0.6, "k2": 60.0, "m2": 4.0},
                                        "std": dict.fromkeys(("m1", "k1", "b1", "k2", "m2"), 0.01),
                                        "source": f"the first 20 s of {csv}"}
    assert results["run"]["noise_estimate"] == pytest.approx(NOISE, rel=0.1)
    assert (results["run"]["noise"], results["run"]["noise_source"]) == (NOISE, "--noise")
    assert (results["run"]["load_noise"], results["run"]["load_noise_source"]) == (0.002, "--load-noise")
    (call,) = commissioned_at_the_truth
    # the record's first 20 s as read (written to 12 digits)
    np.testing.assert_allclose(call["measured"][0], signals[:2001].T, rtol=1e-11, atol=1e-16)
    np.testing.assert_allclose(call["load"][0], load[:2001], rtol=1e-11)
    np.testing.assert_allclose(call["load_rate"][0], np.gradient(load[:2001], 0.01), rtol=1e-6, atol=1e-9)
    assert (call["sample_rate"], call["noise"], call["load_noise"]) == (RATE, NOISE, 0.002)
    assert "healthy machine (commissioned) | m1 8.3 +- 0.01, k1 116 +- 0.01" in (tmp_path / "out_off" / "report.md").read_text()
    assert "commissioned on the first 20 s" in capsys.readouterr().out


@pytest.mark.usefixtures("stand_in_network")
def test_a_separate_healthy_record_commissions_the_machine(tmp_path: Path, commissioned_at_the_truth: list[dict[str, Any]]) -> None:
    t, load, signals = record(60.0, seed=3, **OFF_NOMINAL)
    healthy = write_csv(tmp_path / "healthy.csv", t[:1001], load[:1001], signals[:1001])  # 10 s of another record
    t, load, signals = record(60.0, seed=4, **OFF_NOMINAL)
    results = phm(tmp_path, model_file(tmp_path), write_csv(tmp_path / "data.csv", t, load, signals), "--commission", str(healthy),
                  noise=False)
    (call,) = commissioned_at_the_truth
    assert call["measured"].shape == (1, 4, 1001) and results["commissioning"]["source"] == str(healthy)
    assert results["detection_time"] is None and results["run"]["noise_source"] == "estimated"
    assert results["run"]["noise"] == results["run"]["noise_estimate"] == pytest.approx(NOISE, rel=0.1)
