"""Recorded measurements: the CSV format (written exactly, every bad file named), the streaming chain
(any chunking, the same statuses as the whole record), and ``ea-gym phm --measurements`` end to end."""

import contextlib
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest

from ea_gym.cli import main
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.database import classes_of
from ea_gym.diagnosis.monitor import MonitorConfig
from ea_gym.measurements import MeasurementError, Measurements, noise_estimate, read_measurements, resampled, write_measurements
from ea_gym.models import spring_mass_damper
from ea_gym.phm import ChainTiming, DetectorConfig, PHMChain, PHMConfig, calibrate_thresholds, run_signals
from ea_gym.phm.harness import (
    StreamingChain,
    chain_config,
    chain_sample_rate,
    fitted_initial_state,
    fitted_reference,
    run_measurements,
    scenario_measurements,
)
from ea_gym.plant import run_model
from ea_gym.scenario import load_scenario

MODEL = spring_mass_damper()
NOISE = 0.01
# k falls from 100 N/m at 5 s to 88 N/m at 60 s: it crosses its lower safe limit 85 N/m at
# 5 + 55 x 15 / 12 = 73.75 s, the End of Life a perfect prognosis predicts throughout
FAULT_END_OF_LIFE = 73.75
SCENARIO = {
    "system": "spring_mass_damper",
    "load": {"kind": "sines", "offset": 10.0,
             "sines": [{"amplitude": 5.0, "frequency": 0.3}, {"amplitude": 2.0, "frequency": 1.1, "phase": 0.5}]},
    "duration": 60.0,
    "fault": {"parameter": "k", "profile": [[0, 100], [5, 100], [60, 88]]},
    "sensors": {"noise": NOISE, "seed": 4},
}
HEALTHY = {key: value for key, value in SCENARIO.items() if key != "fault"}


def _write_scenario(directory: Path, scenario: dict, name: str) -> Path:
    path = directory / f"{name}.json"
    path.write_text(json.dumps(scenario))
    return path


# ------------------------------------------------------------------------------------------------
# the CSV format
# ------------------------------------------------------------------------------------------------


def test_written_measurements_read_back_exactly(tmp_path):
    rng = np.random.default_rng(0)
    t = 12.5 + 0.01 * np.arange(50)
    written = Measurements(t=t, load=rng.normal(10, 3, 50), signals=rng.normal(0, 1e-3, (50, 2)))
    read = read_measurements(write_measurements(tmp_path / "m.csv", MODEL, written), MODEL)
    assert (tmp_path / "m.csv").read_text().splitlines()[0] == "t,F,m,k"
    for field in ("t", "load", "signals"):
        np.testing.assert_array_equal(getattr(read, field), getattr(written, field))
    assert read.sample_rate == 100.0 and read.duration == pytest.approx(0.49)


def test_columns_may_come_in_any_order(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("k, m ,F,t\n3,2,1,0\n6,5,4,0.5\n")
    read = read_measurements(path, MODEL)
    np.testing.assert_array_equal(read.t, [0.0, 0.5])
    np.testing.assert_array_equal(read.load, [1.0, 4.0])
    np.testing.assert_array_equal(read.signals, [[2.0, 3.0], [5.0, 6.0]])  # state_names order: m, k


GOOD = ["t,F,m,k", *(f"{i / 100:g},10,{i / 10:g},{i / 5:g}" for i in range(8))]  # 8 samples at 100 Hz


def _with(line: int, text: str | None) -> str:
    """GOOD with its ``line`` (1: the header) replaced by ``text``, or removed when None."""
    lines = list(GOOD)
    if text is None:
        del lines[line - 1]
    else:
        lines[line - 1] = text
    return "\n".join(lines) + "\n"


BAD_CSV = [
    ("missing column", _with(1, "t,F,m,x").replace(",x", ""), "missing column 'k'"),
    ("extra column", "t,F,m,k,T\n0,10,0,0,20\n0.01,10,0,0,20\n", "unexpected column 'T'"),
    ("repeated column", "t,F,m,k,k\n0,10,0,0,0\n", "column 'k' appears twice"),
    ("t not increasing", _with(4, "0.01,10,0.2,0.4"), "line 4: t = 0.01 s does not increase"),
    ("t with a gap", _with(3, None), "line 3: t = 0.02 s is 0.02 s after the line before, not the sampling period 0.01 s"),
    ("NaN cell", _with(3, "0.01,10,nan,0.2"), "line 3, column 'm': 'nan' where a number is expected"),
    ("empty cell", _with(4, "0.02,10,0.2,"), "line 4, column 'k': an empty cell"),
    ("text cell", _with(5, "0.03,ten,0.3,0.6"), "line 5, column 'F': 'ten'"),
    ("overflow", _with(5, "0.03,1e999,0.3,0.6"), "line 5, column 'F': '1e999' overflows a float"),
    ("short row", _with(3, "0.01,10,0.1"), "line 3 has 3 cells, the header 4"),
    ("blank line", _with(3, ""), "line 3 is empty"),
    ("empty file", "", "empty file"),
    ("header only", "t,F,m,k\n", "0 sample(s); a record needs at least 2"),
]


@pytest.mark.parametrize(("text", "fragment"), [case[1:] for case in BAD_CSV], ids=[case[0] for case in BAD_CSV])
def test_bad_csv_names_the_culprit(tmp_path, text, fragment):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(MeasurementError) as error:
        read_measurements(path, MODEL)
    assert fragment in str(error.value)
    assert str(path) in str(error.value)


# ------------------------------------------------------------------------------------------------
# the CSV as people write it: spreadsheets, units, other names, extra channels, other rates
# ------------------------------------------------------------------------------------------------

PLAIN = "\n".join(GOOD) + "\n"


def _read_text(tmp_path, text: str, **options):
    path = tmp_path / "m.csv"
    path.write_bytes(text.encode("utf-8"))
    return read_measurements(path, MODEL, **options)


def _same_record(a: Measurements, b: Measurements) -> bool:
    return all(np.array_equal(getattr(a, name), getattr(b, name)) for name in ("t", "load", "signals"))


def test_a_spreadsheets_csv_reads_as_the_plain_one(tmp_path):
    """A byte-order mark, ";" between cells, "," as the decimal point, units in brackets or parentheses."""
    plain = _read_text(tmp_path, PLAIN)
    rows = [line.replace(",", ";").replace(".", ",") for line in GOOD[1:]]
    spreadsheet = "\ufeff" + "\n".join(["t [s];F (N);m [m/s];k [m]", *rows]) + "\n"
    assert _same_record(_read_text(tmp_path, spreadsheet), plain)
    with_bom = "\ufeff" + PLAIN
    assert _same_record(_read_text(tmp_path, with_bom), plain)


def test_prefixed_units_are_converted_to_si(tmp_path):
    rows = [f"{i * 10},0.01,{i * 100},{i * 200}" for i in range(8)]  # t in ms, F in kN, m in mm/s, k in mm
    read = _read_text(tmp_path, "\n".join(["t [ms],F [kN],m [mm/s],k [mm]", *rows]) + "\n")
    np.testing.assert_allclose(read.t, np.arange(8) / 100, rtol=1e-15)
    np.testing.assert_allclose(read.load, 10.0)
    np.testing.assert_allclose(read.signals, np.column_stack([np.arange(8) / 10, np.arange(8) / 5]), rtol=1e-15)


@pytest.mark.parametrize(
    ("header", "fragment"),
    [
        ("t [s],F [N],m [ft/s],k [m]", "column 'm': unit 'ft/s' is not read (the m column's); expected m/s or a decimal prefix of it"),
        ("t [s],F [N],m [m/s],k [m/s]", "column 'k': unit 'm/s' is not read (the k column's); expected m or a decimal prefix of it"),
        ("t [min],F,m,k", "column 't': unit 'min' is not read (the t column's); expected s"),
        ("t,F [lbf],m,k", "column 'F': unit 'lbf' is not read (the F column's); expected N"),
    ],
)
def test_a_unit_that_is_not_the_columns_si_unit_is_refused(tmp_path, header, fragment):
    with pytest.raises(MeasurementError) as error:
        _read_text(tmp_path, "\n".join([header, *GOOD[1:]]) + "\n")
    assert fragment in str(error.value)


def test_columns_are_mapped_and_extra_channels_ignored_by_name(tmp_path):
    plain = _read_text(tmp_path, PLAIN)
    rows = [f"{line},21.5,ok" for line in GOOD[1:]]
    renamed = "\n".join(["time [s],force,v_body [m/s],x,temperature,note", *rows]) + "\n"
    read = _read_text(tmp_path, renamed, columns={"t": "time", "F": "force", "m": "v_body [m/s]", "k": "x"}, ignore=["temperature", "note"])
    assert _same_record(read, plain)


@pytest.mark.parametrize(
    ("header", "options", "fragment"),
    [
        ("t,F,m,x", {}, "missing column 'k' (model spring_mass_damper needs columns t, F, m, k; found 't', 'F', 'm', 'x'; "
                        "map another column to it with --columns k=COLUMN)"),
        ("t,F,m,k,T", {}, "unexpected column 'T' (model spring_mass_damper needs columns t, F, m, k; found 't', 'F', 'm', 'k', 'T'; "
                          "leave it unread with --ignore-columns T)"),
        ("t,F,m,x", {"columns": {"k": "y"}}, "--columns k=... names column 'y', absent"),
        ("t,F,m,k", {"columns": {"q": "k"}}, "--columns q=...: 'q' is not a column of model spring_mass_damper (t, F, m, k)"),
        ("t,F,m,k", {"ignore": ["T"]}, "--ignore-columns: no column 'T' in the file (found 't', 'F', 'm', 'k')"),
        ("t,F,m,k", {"columns": {"m": "k"}}, "column 'k' is read for both m and k; expected one file column per model column"),
        (",".join(["t", "F", "m", "k", *(f"c{i}" for i in range(30))]), {}, "'c7', ... (34 in all)"),
    ],
)
def test_column_messages_list_what_was_found_and_how_to_map_or_ignore(tmp_path, header, options, fragment):
    width = header.count(",") + 1
    rows = [",".join([line, *["0"] * (width - 4)]) for line in GOOD[1:]]
    with pytest.raises(MeasurementError) as error:
        _read_text(tmp_path, "\n".join([header, *rows]) + "\n", **options)
    assert fragment in str(error.value)


def _rounded(rate: float, samples: int, decimals: int) -> str:
    return "\n".join(["t,F,m,k", *(f"{round(i / rate, decimals)},10,{i},{i}" for i in range(samples))]) + "\n"


def test_rounded_timestamps_need_the_declared_rate_and_then_keep_to_its_grid(tmp_path):
    text = _rounded(256.0, 600, 3)  # 256 Hz written to 1 ms
    jitter = r"line 8: t = 0.023 s is 0.003 s after the line before, .* jitter in the record; timestamps rounded .* --sample-rate HZ"
    with pytest.raises(MeasurementError, match=jitter):
        _read_text(tmp_path, text)
    read = _read_text(tmp_path, text, sample_rate=256.0)
    assert read.sample_rate == 256.0 and np.array_equal(read.t, np.arange(600) / 256.0)
    late = text.replace("\n0.043,", "\n0.045,")  # sample 11, at 42.97 ms, written 45 ms: beyond the 1 ms rounding
    with pytest.raises(MeasurementError, match=r"line 13: t = 0.045 s is \+0.00203125 s off the declared 256 Hz grid .* rounding \(0.001 s\)"):
        _read_text(tmp_path, late, sample_rate=256.0)
    with pytest.raises(MeasurementError, match="off the declared 250 Hz grid"):
        _read_text(tmp_path, text, sample_rate=250.0)


def test_a_non_integer_rate_is_read_and_resampled_for_the_chain_keeping_the_band():
    rate = 204.8
    t = np.arange(2048) / rate
    record = Measurements(t=t, load=10 + np.sin(2 * np.pi * 3 * t), signals=np.column_stack([np.cos(2 * np.pi * 5 * t), np.sin(2 * np.pi * t)]))
    assert record.sample_rate == pytest.approx(rate, rel=1e-12)
    assert chain_sample_rate(record.sample_rate) == 210.0 and chain_sample_rate(100.0) == 100.0 and chain_sample_rate(1.5) == 10.0
    resampled_record = resampled(record, 210.0)
    s = resampled_record.t
    # within the record by the filter's reach (10 samples) at either end, where it has the record on both sides
    assert resampled_record.sample_rate == 210.0 and 10 / rate <= s[0] < 11 / rate and t[-1] - 12 / rate < s[-1] <= t[-1] - 10 / rate
    np.testing.assert_allclose(np.diff(s), 1 / 210.0, rtol=1e-9)
    np.testing.assert_allclose(resampled_record.load, 10 + np.sin(2 * np.pi * 3 * s), atol=1e-5)
    np.testing.assert_allclose(resampled_record.signals, np.column_stack([np.cos(2 * np.pi * 5 * s), np.sin(2 * np.pi * s)]), atol=1e-5)


def test_the_smoothing_window_fits_a_step_at_any_rate_from_10_hz():
    assert chain_config(100.0, 0.01).monitor == MonitorConfig() and chain_config(60.0, 0.0).monitor.smoothing == 51
    assert chain_config(50.0, 0.0).monitor.smoothing == 49 and chain_config(10.0, 0.0).monitor.smoothing == 9
    with pytest.raises(ValueError, match="a chunk of 9 samples holds no smoothing window above the polynomial order 7"):
        MonitorConfig().fitting(8)


def test_only_regular_files_within_the_limits_are_read(tmp_path):
    with pytest.raises(MeasurementError, match="must be a regular file"):
        read_measurements(tmp_path, MODEL)
    with pytest.raises(MeasurementError, match="cannot read"):
        read_measurements(tmp_path / "absent.csv", MODEL)
    path = tmp_path / "m.csv"
    path.write_text("\n".join(GOOD) + "\n")
    size = path.stat().st_size
    with pytest.raises(MeasurementError, match=f"{size} bytes, more than the {size - 1} read"):
        read_measurements(path, MODEL, max_bytes=size - 1)
    with pytest.raises(MeasurementError, match="8 lines after the header, more than the 7 samples read"):
        read_measurements(path, MODEL, max_rows=7)
    assert len(read_measurements(path, MODEL, max_bytes=size, max_rows=8).t) == 8


@pytest.mark.parametrize("noise", [0.0, 0.005, 0.01, 0.03])
def test_noise_estimate_reads_the_sensor_noise_of_a_record(noise):
    record = scenario_measurements(load_scenario(dict(SCENARIO, duration=20.0, sensors={"noise": noise, "seed": 3})), np.random.default_rng(0))
    assert noise_estimate(record, MODEL, 100) == pytest.approx(noise, abs=0.05 * noise + 2e-4)


# ------------------------------------------------------------------------------------------------
# the streaming chain
# ------------------------------------------------------------------------------------------------


class _Uniform(FaultClassifier):
    """A stand-in network without an opinion (no training in tests): isolation rests on the estimator."""

    def predict_proba(self, features):
        return np.full((len(features), 4), 0.25)


@pytest.fixture(scope="module")
def chain():
    config = PHMConfig(timing=ChainTiming(noise=NOISE), detector=DetectorConfig(calibration_runs=2, calibration_duration=20.0, balance_span=20.0))
    thresholds = calibrate_thresholds(MODEL, config, np.random.default_rng(2))
    return PHMChain(MODEL, _Uniform(classes_of(MODEL), "strong", 1), thresholds, config)


@pytest.fixture(scope="module")
def record():
    short = dict(SCENARIO, duration=30.0, fault={"parameter": "k", "profile": [[0, 100], [5, 100], [30, 92]]})
    return scenario_measurements(load_scenario(short), np.random.default_rng(1))


def _same(a, b) -> bool:
    return all(
        np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True)
        for name in ("t", "ea", "ea_reference", "statistic", "alarm", "diagnosis", "isolated", "estimates", "eol", "eol_low", "eol_high")
    )


def test_streaming_in_random_chunks_gives_the_statuses_of_one_chunk(chain, record):
    whole = StreamingChain(chain)
    statuses = whole.feed(record.t, record.load, record.signals) + whole.finish()
    assert len(statuses) == 30 and statuses[-1].alarm[0]  # the fault is seen: the comparison is not vacuous
    rng = np.random.default_rng(7)
    stream, chunked, start = StreamingChain(chain), [], 0
    while start < len(record.t):
        size = int(rng.integers(1, 250))
        chunked += stream.feed(record.t[start : start + size], record.load[start : start + size], record.signals[start : start + size])
        start += size
    chunked += stream.finish()
    assert len(chunked) == len(statuses) == len(stream.statuses)
    assert all(_same(a, b) for a, b in zip(statuses, chunked))


def test_streaming_equals_run_signals_on_the_whole_record(chain, record):
    """The reference implementation: ``run_signals`` with the nominal model from the first sample and the
    load's central-difference derivative over the whole record."""
    measured = record.signals.T[None]
    load = record.load[None]
    load_rate = np.gradient(load, chain.h, axis=-1)
    expected = run_signals(chain, measured, load, load_rate, fitted_reference(chain, measured, load, load_rate))
    streamed = run_measurements(chain, record).statuses
    assert len(streamed) == len(expected) == 30
    assert all(_same(a, b) for a, b in zip(expected, streamed))


def test_stream_refuses_a_gap_between_chunks_and_bad_shapes(chain, record):
    stream = StreamingChain(chain)
    stream.feed(record.t[:10], record.load[:10], record.signals[:10])
    with pytest.raises(ValueError, match=r"sample 10: t = 0.11 s is 0.02 s after the one before; the chain samples every 0.01 s"):
        stream.feed(record.t[11:20], record.load[11:20], record.signals[11:20])
    with pytest.raises(ValueError, match=r"signals \(T, 2\)"):
        stream.feed(record.t[10:20], record.load[10:20], record.signals[10:20, :1])
    signals = record.signals[10:20].copy()
    signals[3, 1] = np.nan
    with pytest.raises(ValueError, match="sample 13: t, load and signals must be finite"):
        stream.feed(record.t[10:20], record.load[10:20], signals)
    assert stream.received == 10  # nothing of a refused chunk is kept


def test_the_reference_starts_from_the_state_fitted_to_the_first_step_not_from_one_noisy_sample(chain):
    """A record cut from a running healthy machine (20 s in), 1 % noise: the fitted energy variables are
    within 0.1 % of each one's range of the true ones, less than half the first sample's error."""
    scenario = load_scenario(HEALTHY)
    plant = run_model(MODEL, scenario.times(), scenario.make_load(), None, scenario.initial_state_vector())
    record = scenario_measurements(scenario, np.random.default_rng(5))
    part = slice(2000, 2000 + chain.step_samples + 1)
    load = record.load[None, part]
    fitted = fitted_initial_state(chain, record.signals[part].T[None], load, np.gradient(load, chain.h, axis=-1))[0]
    true = plant.states[2000]
    scale = np.ptp(plant.states, axis=0)
    fitted_error = np.abs(fitted - true) / scale
    sample = record.signals[2000] / chain.sensors.gain(MODEL.parameter_vector())
    sample_error = np.abs(sample - true) / scale  # 2.0e-3 and 0.8e-3 of the ranges here
    assert np.all(fitted_error < 1e-3) and fitted_error.max() < 0.5 * sample_error.max()  # 0.45e-3, 0.35e-3


def test_a_record_shorter_than_a_detection_window_is_refused(chain, record):
    with pytest.raises(ValueError, match=r"lasts 4.99 s; the chain needs at least 5 s \(one detection window\), i.e. 501 samples at 100 Hz"):
        run_measurements(chain, Measurements(record.t[:500], record.load[:500], record.signals[:500]))


# ------------------------------------------------------------------------------------------------
# ea-gym simulate --csv and ea-gym phm --measurements
# ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def recorded_runs(tmp_path_factory):
    """The fault and the fault-free scenarios' CSVs written by the CLI, each run through ``phm --measurements``."""
    directory = tmp_path_factory.mktemp("recorded")
    outputs = {}
    for name, scenario in (("fault", SCENARIO), ("healthy", HEALTHY)):
        csv = directory / f"{name}.csv"
        assert main(["simulate", str(_write_scenario(directory, scenario, name)), "--csv", str(csv)]) == 0
        out = directory / f"{name}_out"
        args = ["phm", "--system", "spring_mass_damper", "--measurements", str(csv), "--noise", str(NOISE), "--out", str(out)]
        printed = io.StringIO()
        with contextlib.redirect_stdout(printed):
            assert main(args) == 0
        outputs[name] = (csv, out, json.loads((out / "results.json").read_text()), printed.getvalue())
    return outputs


def test_simulate_csv_is_the_scenarios_sensor_record(recorded_runs):
    csv, _, _, _ = recorded_runs["fault"]
    read = read_measurements(csv, MODEL)
    scenario = load_scenario(SCENARIO)
    expected = scenario_measurements(scenario, np.random.default_rng(scenario.sensor_seed))
    np.testing.assert_array_equal(read.signals, expected.signals)
    np.testing.assert_array_equal(read.t, np.arange(6001) / 100.0)
    # 1 % noise: the velocity's deviation from its clean value over the first step is about 1 % of its RMS
    clean = scenario_measurements(load_scenario(dict(SCENARIO, sensors={"noise": 0.0})), np.random.default_rng(0))
    deviation = read.signals[:100, 0] - clean.signals[:100, 0]
    assert 0.005 < deviation.std() / np.sqrt(np.mean(clean.signals[:100, 0] ** 2)) < 0.015


def test_recorded_fault_is_detected_isolated_tracked_and_its_end_of_life_predicted(recorded_runs):
    csv, out, results, printed = recorded_runs["fault"]
    assert results["isolated_parameter"] == "k"
    assert 5.0 < results["detection_time"] < 15.0
    assert f"detection at {results['detection_time']:g} s, isolated parameter k; wrote {out}/results.json" in printed
    # tracked: the estimate follows k's ramp 100 -> 88 N/m from 5 s (truth known from the scenario)
    t, value = np.array(results["estimate"]["t"]), np.array(results["estimate"]["value"])
    late = t >= 20.0
    truth = 100.0 - 12.0 * (t[late] - 5.0) / 55.0
    assert np.max(np.abs(value[late] - truth)) < 1.0  # N/m, 1 % of nominal
    # End of Life: every prediction of the last 20 s within 5 % of the true 73.75 s
    predictions = [p for p in results["eol_predictions"] if p["t"] >= 40.0]
    assert len(predictions) == 21 and all(p["parameter"] == "k" and p["limit"] == "lower" for p in predictions)
    errors = np.array([p["eol"] for p in predictions]) - FAULT_END_OF_LIFE
    assert np.max(np.abs(errors)) < 0.05 * FAULT_END_OF_LIFE
    # no truth: no metrics, no estimate-error figure, nothing the report claims to know of it
    assert "metrics" not in results and results["run"]["measurements"] == str(csv) and "scenario" not in results["run"]
    assert sorted(p.name for p in out.iterdir()) == ["estimate.png", "report.md", "results.json", "rul.png", "signals.png", "time_frequency.png"]
    report = (out / "report.md").read_text()
    assert "truth unknown" in report and "true" not in report.replace("truth unknown", "")
    last, estimate = results["eol_predictions"][-1], results["estimate"]
    assert f"| latest End of Life (s) | {last['eol']:.4g} (k at its lower limit, predicted at {last['t']:g} s) |" in report
    assert f"| latest RUL (s) [low, high] | {last['rul']:.4g} [{last['rul_low']:.4g}, {last['rul_high']:.4g}] |" in report
    assert f"| latest estimate of k | {estimate['value'][-1]:.4g} at {estimate['t'][-1]:g} s |" in report


def test_recorded_healthy_machine_raises_no_alarm(recorded_runs):
    _, out, results, printed = recorded_runs["healthy"]
    assert results["detection_time"] is None and results["isolated_parameter"] is None
    assert results["eol_predictions"] == []
    assert printed.splitlines()[-1] == f"no fault detected; wrote {out}/results.json and report.md"
    assert "latest End of Life" not in (out / "report.md").read_text()


CLI_ERRORS = [
    ("missing column", "t,F,k\n0,1,2\n0.01,1,2\n", "missing column 'm'"),
    ("extra column", "t,F,m,k,x\n0,1,2,3,4\n", "unexpected column 'x'"),
    ("NaN", _with(4, "0.02,10,NaN,0.4"), "line 4, column 'm': 'NaN'"),
    ("gap", _with(4, None), "line 4: t = 0.03 s"),
    ("t not increasing", _with(6, "0.03,10,0.4,0.8"), "line 6: t = 0.03 s does not increase"),
    ("too short", "\n".join(GOOD) + "\n", "the record lasts 0.07 s; the chain needs at least 5 s"),
]


@pytest.mark.parametrize(("text", "fragment"), [case[1:] for case in CLI_ERRORS], ids=[case[0] for case in CLI_ERRORS])
def test_phm_measurements_errors_exit_2_in_one_line_writing_nothing(tmp_path, capsys, text, fragment):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    out = tmp_path / "out"
    assert main(["phm", "--system", "spring_mass_damper", "--measurements", str(path), "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("ea-gym phm: error: ") and fragment in error and error.count("\n") == 1
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--measurements", "x.csv"], "--measurements needs --system MODEL"),
        ([], "give a SCENARIO to simulate or --measurements DATA.csv"),
        (["s.json", "--measurements", "x.csv", "--system", "spring_mass_damper"], "one of them"),
        (["s.json", "--noise", "0.01"], "--noise goes with --measurements"),
        (["s.json", "--seed", "3"], "--seed goes with --measurements"),
        (["--system", "nonsense", "--measurements", "x.csv"], "unknown system 'nonsense'"),
        (["s.json", "--columns", "m=v"], "--columns goes with --measurements"),
        (["s.json", "--ignore-columns", "T"], "--ignore-columns goes with --measurements"),
        (["s.json", "--sample-rate", "256"], "--sample-rate goes with --measurements"),
        (["--system", "spring_mass_damper", "--measurements", "x.csv", "--columns", "m=a", "--columns", "m=b"],
         "--columns: 'm' is mapped twice ('a' and 'b')"),
    ],
)
def test_phm_options_that_do_not_go_together(tmp_path, capsys, args, fragment):
    assert main(["phm", *args, "--out", str(tmp_path / "out")]) == 2
    assert fragment in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("option", "fragment"),
    [
        (["--columns", "m"], "argument --columns: expected NAME=COLUMN (the model's column, the file's), got 'm'"),
        (["--ignore-columns", "a,,b"], "argument --ignore-columns: expected column names separated by commas, got 'a,,b'"),
        (["--sample-rate", "nan"], "argument --sample-rate: expected a sample rate in Hz > 0, got 'nan'"),
    ],
)
def test_phm_measurement_options_refuse_bad_values_in_one_line(tmp_path, capsys, option, fragment):
    with pytest.raises(SystemExit) as exit_:
        main(["phm", "--system", "spring_mass_damper", "--measurements", "x.csv", *option, "--out", str(tmp_path / "out")])
    error = capsys.readouterr().err
    assert exit_.value.code == 2 and fragment in error and error.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_phm_measurements_calibrates_at_the_records_noise_unless_told_and_warns_when_told_too_low(tmp_path, capsys):
    scenario = load_scenario(dict(HEALTHY, duration=8.0))
    record = scenario_measurements(scenario, np.random.default_rng(0))
    csv = write_measurements(tmp_path / "m.csv", MODEL, record)
    assert main(["phm", "--system", "spring_mass_damper", "--measurements", str(csv), "--out", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    estimate = re.search(r"The record's sensor noise looks like ([0-9.]+)% of the signals' RMS", captured.out)
    assert estimate is not None and 0.9 < float(estimate.group(1)) < 1.1  # the record's 1 %
    assert f"calibrated for {estimate.group(1)}% (the record's estimate)" in captured.out
    assert "warning" not in captured.err
    assert json.loads((tmp_path / "out" / "results.json").read_text())["detection_time"] is None  # healthy: no alarm
    assert estimate.group(0) in (tmp_path / "out" / "report.md").read_text()

    assert main(["phm", "--system", "spring_mass_damper", "--measurements", str(csv), "--noise", "0", "--out", str(tmp_path / "low")]) == 0
    captured = capsys.readouterr()
    assert "calibrated for 0.00% (--noise)" in captured.out
    assert "ea-gym phm: warning: --noise 0 is likely too low for this record" in captured.err


def test_phm_help_says_how_to_choose_the_noise(capsys):
    with pytest.raises(SystemExit):
        main(["phm", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for phrase in ("--measurements", "--system", "--noise", "fault-free stretch", "Too low raises alarms"):
        assert phrase in text


# ------------------------------------------------------------------------------------------------
# issue 19's acceptance: a model file's machine, a fault in its coupling spring k2
# ------------------------------------------------------------------------------------------------

TWO_MASS = Path(__file__).resolve().parents[1] / "experiments" / "models" / "two_mass_chain.yaml"
# k2 falls from 50 N/m at 5 s to 40 N/m at 60 s: it crosses its lower safe limit 42 N/m at 5 + 55 x 8 / 10 = 49 s
K2_END_OF_LIFE = 49.0


@pytest.fixture(scope="module")
def two_mass_runs(tmp_path_factory):
    """The two-mass chain's fault and fault-free records through ``phm --measurements``, with a small isolation
    network trained here (a few seconds: 4 intervals per parameter, 2 loads; the chain's fusion with the
    estimator's evidence does the rest)."""
    from ea_gym.diagnosis.database import DatabaseConfig
    from ea_gym.diagnosis.training import TrainingConfig, train_isolation
    from ea_gym.model_files import load_system

    directory = tmp_path_factory.mktemp("two_mass")
    database = DatabaseConfig(intervals=4, noise_levels=(NOISE,), n_loads=2, fault_free_runs=2)
    training = train_isolation(load_system(str(TWO_MASS)), np.random.default_rng(0), database, TrainingConfig(epochs=100), variants=("strong",))
    network = training.classifiers["strong"].save(directory / "network.pt")
    load = {"kind": "sines", "offset": 10.0, "sines": [{"amplitude": 4.0, "frequency": 0.25}, {"amplitude": 2.0, "frequency": 0.55},
                                                       {"amplitude": 1.0, "frequency": 1.1}]}
    scenarios = {
        "fault": {"system": str(TWO_MASS), "load": load, "duration": 60.0, "sensors": {"noise": NOISE, "seed": 21},
                  "fault": {"parameter": "k2", "profile": [[0, 50], [5, 50], [60, 40]]}},
        "healthy": {"system": str(TWO_MASS), "load": load, "duration": 60.0, "sensors": {"noise": NOISE, "seed": 22}},
    }
    results = {}
    for name, scenario in scenarios.items():
        csv = directory / f"{name}.csv"
        assert main(["simulate", str(_write_scenario(directory, scenario, name)), "--csv", str(csv)]) == 0
        out = directory / f"{name}_out"
        assert main(["phm", "--system", str(TWO_MASS), "--measurements", str(csv), "--noise", str(NOISE), "--classifier", str(network),
                     "--out", str(out)]) == 0
        results[name] = json.loads((out / "results.json").read_text())
    return results


def test_two_mass_chain_coupling_spring_fault_is_isolated_tracked_and_its_end_of_life_predicted(two_mass_runs):
    results = two_mass_runs["fault"]
    assert results["isolated_parameter"] == "k2" and results["class_probabilities"]["k2"] > 0.9
    t, value = np.array(results["estimate"]["t"]), np.array(results["estimate"]["value"])
    late = t >= 20.0
    truth = 50.0 - 10.0 * (t[late] - 5.0) / 55.0
    assert late.sum() > 30 and np.max(np.abs(value[late] - truth)) < 1.0  # N/m, 2 % of nominal
    predictions = [p for p in results["eol_predictions"] if 25.0 <= p["t"] < 45.0]
    assert len(predictions) == 20 and all(p["parameter"] == "k2" and p["limit"] == "lower" for p in predictions)
    errors = np.array([p["eol"] for p in predictions]) - K2_END_OF_LIFE
    assert np.max(np.abs(errors)) < 0.05 * K2_END_OF_LIFE


def test_two_mass_chain_healthy_record_raises_no_alarm(two_mass_runs):
    results = two_mass_runs["healthy"]
    assert results["detection_time"] is None and results["isolated_parameter"] is None and results["eol_predictions"] == []


# ------------------------------------------------------------------------------------------------
# issue 32's acceptance: a quarter car on a road (a zero-mean velocity source as the load), its records
# made by scipy's solve_ivp (not ea-gym's simulator) and written as people write them
# ------------------------------------------------------------------------------------------------

QUARTER_CAR = """\
name: quarter_car
description: a car's corner on a road whose vertical velocity zr drives the tyre
elements:
  zr: {kind: Sf, unit: m/s}
  tyre: {kind: "0"}
  kt: {kind: C, form: stiffness, value: 50000.0, unit: N/m}
  wheel: {kind: "1"}
  mu: {kind: I, value: 40.0, unit: kg}
  strut: {kind: "0"}
  stroke: {kind: "1"}
  ks: {kind: C, form: stiffness, value: 16000.0, unit: N/m, limits: [13000.0, 17000.0]}
  cs: {kind: R, value: 1000.0, unit: N s/m, limits: [800.0, 1200.0]}
  body: {kind: "1"}
  ms: {kind: I, value: 250.0, unit: kg, limits: [230.0, 270.0]}
bonds: [[zr, tyre], [tyre, kt], [tyre, wheel], [wheel, mu], [wheel, strut], [strut, stroke], [stroke, ks], [stroke, cs],
        [strut, body], [body, ms]]
load: {source: zr, nominal: 0.0, scale: 0.1, bandwidth: 5.0}
"""


def _road_velocity(t: np.ndarray) -> np.ndarray:
    """A zero-mean road velocity (m/s)."""
    return 0.05 * np.sin(2 * np.pi * 1.3 * t) + 0.03 * np.sin(2 * np.pi * 3.1 * t + 1.0) + 0.02 * np.sin(2 * np.pi * 0.7 * t + 2.0)


def _quarter_car_record(
    rate: float, duration: float, noise: float = NOISE, parts: tuple[float, ...] = (50000.0, 40.0, 16000.0, 1000.0, 250.0)
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """t, the road velocity and the signals (tyre deflection, wheel velocity, strut deflection, body velocity: the model's
    states kt, mu, ks, ms) of the quarter car's own equations (``parts``: kt, mu, ks, cs, ms) integrated by solve_ivp, with
    sensor noise."""
    from scipy.integrate import solve_ivp

    kt, mu, ks, cs, ms = parts

    def motion(time: float, x: np.ndarray) -> list[float]:
        tyre, wheel, strut, body = x
        strut_force = ks * strut + cs * (wheel - body)
        return [float(_road_velocity(np.array(time))) - wheel, (kt * tyre - strut_force) / mu, wheel - body, strut_force / ms]

    t = np.arange(round(duration * rate) + 1) / rate
    states = solve_ivp(motion, (0.0, t[-1]), np.zeros(4), t_eval=t, method="DOP853", rtol=1e-10, atol=1e-12).y.T
    rng = np.random.default_rng(3)
    noisy = states + noise * np.sqrt(np.mean(states**2, axis=0)) * rng.standard_normal(states.shape)
    return t, _road_velocity(t), noisy


@pytest.fixture(scope="module")
def quarter_car(tmp_path_factory):
    """The quarter car's model file and a small isolation network for it (a few seconds; healthy records need no verdict)."""
    from ea_gym.diagnosis.database import DatabaseConfig
    from ea_gym.diagnosis.training import TrainingConfig, train_isolation
    from ea_gym.model_files import load_model_file

    directory = tmp_path_factory.mktemp("quarter_car")
    model_path = directory / "quarter_car.yaml"
    model_path.write_text(QUARTER_CAR)
    database = DatabaseConfig(intervals=1, noise_levels=(NOISE,), n_loads=1, fault_free_runs=1)
    training = train_isolation(load_model_file(model_path), np.random.default_rng(0), database, TrainingConfig(epochs=5), variants=("strong",))
    return model_path, training.classifiers["strong"].save(directory / "network.safetensors")


def _phm(quarter_car, csv: Path, out: Path, *options: str) -> int:
    model, network = quarter_car
    return main(["phm", "--system", str(model), "--measurements", str(csv), "--classifier", str(network), "--noise", str(NOISE),
                 "--out", str(out), *options])


def test_quarter_car_at_50_hz_from_a_spreadsheet_runs_healthy(quarter_car, tmp_path, capsys):
    """50 Hz (the model check asks for 12.7 Hz): a BOM, ';' and decimal commas, units in the header (ms, mm/s, mm), other
    names mapped with --columns, a temperature channel left unread with --ignore-columns."""
    t, road, signals = _quarter_car_record(50.0, 12.0)
    header = "time [ms];road (mm/s);kt [m];mu [m/s];ks [mm];body velocity [m/s];temperature [degC]"
    rows = [";".join(f"{value:.9g}".replace(".", ",") for value in (1e3 * t[k], 1e3 * road[k], signals[k, 0], signals[k, 1],
                                                                  1e3 * signals[k, 2], signals[k, 3], 21.5)) for k in range(len(t))]
    csv = tmp_path / "corner.csv"
    csv.write_text("\ufeff" + "\n".join([header, *rows]) + "\n", encoding="utf-8")
    out = tmp_path / "out"
    assert _phm(quarter_car, csv, out, "--columns", "t=time", "--columns", "zr=road", "--columns", "ms=body velocity",
                "--ignore-columns", "temperature") == 0
    assert capsys.readouterr().out.splitlines()[-1] == f"no fault detected; wrote {out}/results.json and report.md"
    results = json.loads((out / "results.json").read_text())
    assert results["detection_time"] is None and results["run"]["sample_rate"] == 50.0 and results["run"]["duration"] == 12.0


def test_quarter_car_at_204_8_hz_with_rounded_timestamps_runs_at_the_declared_rate(quarter_car, tmp_path, capsys):
    """204.8 Hz written to 1 ms: refused as jitter until --sample-rate states the rate; then resampled to 210 Hz."""
    t, road, signals = _quarter_car_record(204.8, 8.0)
    rows = [",".join([f"{t[k]:.3f}", *(f"{value:.9g}" for value in (road[k], *signals[k]))]) for k in range(len(t))]
    csv = tmp_path / "corner.csv"
    csv.write_text("\n".join(["t [s],zr [m/s],kt [m],mu [m/s],ks [m],ms [m/s]", *rows]) + "\n")
    out = tmp_path / "out"
    assert _phm(quarter_car, csv, out) == 2
    error = capsys.readouterr().err
    assert "jitter in the record; timestamps rounded to fewer decimals than the period needs: declare the rate with --sample-rate HZ" in error
    assert error.count("\n") == 1 and not out.exists()
    assert _phm(quarter_car, csv, out, "--sample-rate", "204.8") == 0
    printed = capsys.readouterr().out
    assert "The record's 204.8 Hz are resampled to 210 Hz" in printed and printed.splitlines()[-1].startswith("no fault detected")
    results = json.loads((out / "results.json").read_text())
    assert results["detection_time"] is None and results["run"]["sample_rate"] == 210.0


@pytest.mark.parametrize(("rate", "noise"), [(100.0, 0.0), (100.0, 0.005), (100.0, 0.01), (100.0, 0.03), (50.0, 0.0), (50.0, 0.01)])
def test_noise_estimate_reads_a_fast_models_sensor_noise_from_its_own_residuals(tmp_path, rate, noise):
    """The quarter car's 10-15 Hz wheel hop, which a fixed 21-sample smoother took for noise (at 50 Hz: 4.8 % without
    noise and at 1 %): measured 0, 0.464, 0.967 and 2.99 % at 100 Hz, 0.047 and 0.99 % at 50 Hz."""
    from ea_gym.model_files import load_model_file

    path = tmp_path / "quarter_car.yaml"
    path.write_text(QUARTER_CAR)
    t, road, signals = _quarter_car_record(rate, 20.0, noise)
    estimate = noise_estimate(Measurements(t, road, signals), load_model_file(path), round(rate))
    assert estimate < 0.002 if noise == 0.0 else estimate == pytest.approx(noise, rel=0.15)


def test_the_quarter_cars_right_noise_draws_no_warning_and_a_wrong_one_does(quarter_car, tmp_path, capsys):
    t, road, signals = _quarter_car_record(100.0, 12.0)
    csv = tmp_path / "corner.csv"
    csv.write_text("\n".join(["t,zr,kt,mu,ks,ms", *(",".join(f"{v:.12g}" for v in (t[k], road[k], *signals[k])) for k in range(len(t)))]) + "\n")
    assert _phm(quarter_car, csv, tmp_path / "right") == 0
    captured = capsys.readouterr()
    assert "warning" not in captured.err and "The record's sensor noise looks like 0.9" in captured.out
    model, network = quarter_car
    for noise, word in (("0.004", "low"), ("0.03", "high")):
        assert main(["phm", "--system", str(model), "--measurements", str(csv), "--classifier", str(network), "--noise", noise,
                     "--out", str(tmp_path / noise)]) == 0
        assert f"ea-gym phm: warning: --noise {noise} is likely too {word}" in capsys.readouterr().err


# a stiff corner (tyre 160 kN/m on a 35 kg wheel): the expm of its transition rounds at 4e-11 (100 Hz) to 2e-10 (50 Hz) of
# the largest entry, above the interpolant's rtol of 1e-11 at every degree
STIFF_PARTS = (160000.0, 35.0, 16000.0, 1000.0, 300.0)
STIFF_QUARTER_CAR = (QUARTER_CAR.replace("value: 50000.0", "value: 160000.0").replace("value: 40.0", "value: 35.0")
                     .replace("value: 250.0, unit: kg, limits: [230.0, 270.0]", "value: 300.0, unit: kg, limits: [280.0, 320.0]"))


@pytest.mark.parametrize("rate", [50.0, 100.0])
def test_a_stiff_quarter_cars_interpolant_is_accepted_on_its_evaluations_rounding_floor(tmp_path, rate):
    """No degree reaches rtol; the lowest on the floor is taken, and it matches direct evaluation to the error it reports,
    at its check points and at points it never saw."""
    from numpy.polynomial import chebyshev

    from ea_gym.model_files import load_model_file
    from ea_gym.phm.tracking import FLOOR_BOUND, discretization_fit, transition

    (tmp_path / "model.yaml").write_text(STIFF_QUARTER_CAR)
    model = load_model_file(tmp_path / "model.yaml")
    base = model.parameter_vector()
    for name in ("ks", "cs", "ms"):
        index = model.state_space.parameter_names.index(name)
        lo, hi = 0.5 * model.safe_limits[name][0], 1.5 * model.safe_limits[name][1]
        coefficients, error = discretization_fit(model, index, lo, hi, 1.0 / rate)
        assert 1e-11 < error <= FLOOR_BOUND and len(coefficients) <= 17
        for s, allowed in ((chebyshev.chebpts2(129), error), (np.random.default_rng(0).uniform(-1.0, 1.0, 200), 3.0 * error)):
            theta = np.repeat(base[None], len(s), axis=0)
            theta[:, index] = lo + (s + 1.0) * 0.5 * (hi - lo)
            exact = transition(model, theta, 1.0 / rate)
            approx = chebyshev.chebval(s, coefficients.reshape(len(coefficients), -1)).T.reshape(exact.shape)
            assert np.max(np.abs(approx - exact)) <= allowed * np.abs(exact).max()


def test_a_stiff_quarter_car_record_at_100_hz_runs_healthy(tmp_path, capsys):
    """Issue 32: a rate the model check accepts runs, the stiff corner too (its record by solve_ivp, 1 % noise)."""
    from ea_gym.diagnosis.database import DatabaseConfig
    from ea_gym.diagnosis.training import TrainingConfig, train_isolation
    from ea_gym.model_files import load_model_file

    model_path = tmp_path / "stiff.yaml"
    model_path.write_text(STIFF_QUARTER_CAR)
    database = DatabaseConfig(intervals=1, noise_levels=(NOISE,), n_loads=1, fault_free_runs=1)
    training = train_isolation(load_model_file(model_path), np.random.default_rng(0), database, TrainingConfig(epochs=5), variants=("strong",))
    network = training.classifiers["strong"].save(tmp_path / "network.safetensors")
    t, road, signals = _quarter_car_record(100.0, 30.0, parts=STIFF_PARTS)
    csv = tmp_path / "corner.csv"
    csv.write_text("\n".join(["t,zr,kt,mu,ks,ms", *(",".join(f"{v:.9g}" for v in (t[k], road[k], *signals[k])) for k in range(len(t)))]) + "\n")
    out = tmp_path / "out"
    assert main(["phm", "--system", str(model_path), "--measurements", str(csv), "--classifier", str(network), "--noise", str(NOISE),
                 "--out", str(out)]) == 0
    assert capsys.readouterr().out.splitlines()[-1].startswith("no fault detected")
    results = json.loads((out / "results.json").read_text())
    assert results["detection_time"] is None and results["isolated_parameter"] is None and results["run"]["sample_rate"] == 100.0


QUARTER_CAR_ERRORS = [
    ("a C element without its form", QUARTER_CAR.replace("ks: {kind: C, form: stiffness,", "ks: {kind: C,"), "t,zr,kt,mu,ks,ms",
     "elements.ks.form: expected stiffness (effort = value x q) or compliance (effort = q / value), got nothing"),
    ("a zero-mean load without its scale", QUARTER_CAR.replace(" scale: 0.1,", ""), "t,zr,kt,mu,ks,ms",
     "load.scale: missing: a zero-mean load (nominal 0) needs the size of its variation"),
    ("a unit not the column's", QUARTER_CAR, "t,zr [km/h],kt,mu,ks,ms", "column 'zr': unit 'km/h' is not read (the zr column's); expected m/s"),
    ("a missing column", QUARTER_CAR, "t,zr,kt,mu,ks,v_body",
     "missing column 'ms' (model quarter_car needs columns t, zr, kt, mu, ks, ms; found 't', 'zr', 'kt', 'mu', 'ks', 'v_body'"),
    ("an extra channel", QUARTER_CAR, "t,zr,kt,mu,ks,ms,T", "unexpected column 'T' (model quarter_car needs"),
]


@pytest.mark.parametrize(("model", "header", "fragment"), [case[1:] for case in QUARTER_CAR_ERRORS], ids=[case[0] for case in QUARTER_CAR_ERRORS])
def test_quarter_car_bad_inputs_exit_2_in_one_line_writing_nothing(tmp_path, capsys, model, header, fragment):
    (tmp_path / "model.yaml").write_text(model)
    t, road, signals = _quarter_car_record(50.0, 1.0)
    width = header.count(",") + 1
    rows = [",".join(f"{value:.9g}" for value in (t[k], road[k], *signals[k], *[0.0] * (width - 6))) for k in range(len(t))]
    (tmp_path / "corner.csv").write_text("\n".join([header, *rows]) + "\n")
    out = tmp_path / "out"
    assert main(["phm", "--system", str(tmp_path / "model.yaml"), "--measurements", str(tmp_path / "corner.csv"), "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("ea-gym phm: error: ") and fragment in error and error.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["corner.csv", "model.yaml"]


def test_a_rate_near_the_model_checks_least_runs_resampled(tmp_path, capsys):
    """The spring-mass-damper's model check accepts 1.01 Hz: a 1.5 Hz record (solve_ivp, noise-free) is resampled to
    10 Hz, where a step of 10 samples takes a 9-sample smoothing window, and the healthy machine raises no alarm."""
    from scipy.integrate import solve_ivp

    def force(t):
        return 10.0 + 3.0 * np.sin(2 * np.pi * 0.2 * t) + 2.0 * np.sin(2 * np.pi * 0.45 * t + 1.0)

    t = np.arange(91) / 1.5
    m, k, b = (MODEL.nominal[name] for name in ("m", "k", "b"))
    motion = solve_ivp(lambda s, x: [(force(s) - k * x[1] - b * x[0]) / m, x[0]], (0.0, t[-1]), [0.0, 0.0], t_eval=t, rtol=1e-10, atol=1e-12)
    csv = write_measurements(tmp_path / "slow.csv", MODEL, Measurements(t=t, load=force(t), signals=motion.y.T))
    out = tmp_path / "out"
    assert main(["phm", "--system", "spring_mass_damper", "--measurements", str(csv), "--noise", str(NOISE), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "The record's 1.5 Hz are resampled to 10 Hz" in printed and printed.splitlines()[-1].startswith("no fault detected")
    results = json.loads((out / "results.json").read_text())
    assert results["run"]["sample_rate"] == 10.0 and results["detection_time"] is None
