"""The design search driven step by step from Python without a cluster: results told in
pieces keep their generation open, and finish() before the end changes nothing."""

import pathlib

import pytest

from tdpcr.optim import DesignSearch, SearchProblem

CONFIG = pathlib.Path(__file__).resolve().parent / "data" / "tiny_search.ron"


def test_a_generation_told_in_pieces_stays_open(tmp_path):
    search = DesignSearch(str(CONFIG), str(tmp_path / "run"), budget_evals=4, seed=9)
    problem = SearchProblem(search.problem)
    search.tell([problem.evaluate(c) for c in search.ask()])  # the reference
    # finish() before the end: an error, and the search goes on.
    with pytest.raises(ValueError, match="before the search has ended"):
        search.finish("test", 1)
    generation = search.ask()
    assert len(generation) >= 2
    search.tell([problem.evaluate(generation[0])])
    assert search.termination is None
    assert search.ask() == generation[1:]
    search.tell([problem.evaluate(c) for c in generation[1:]])
    while candidates := search.ask():
        search.tell([problem.evaluate(c) for c in candidates])
    assert "budget" in search.termination
    summary = search.finish("test", 1)
    assert summary["candidates"] == 4


def test_results_told_out_of_turn_are_named_in_words(tmp_path):
    search = DesignSearch(str(CONFIG), str(tmp_path / "run"), budget_evals=4, seed=9)
    search.ask()
    # Rust's Option leaked into the message ("candidate None").
    with pytest.raises(ValueError, match="^no result told out of turn: expected the reference"):
        search.tell([])


def test_a_directory_in_use_and_an_empty_path_are_refused(tmp_path):
    out = str(tmp_path / "run")
    first = DesignSearch(str(CONFIG), out, budget_evals=4, seed=9)
    # A second search on the same directory would have started its log over the first's.
    with pytest.raises(ValueError, match="in use by another search"):
        DesignSearch(str(CONFIG), out, budget_evals=4, seed=9)
    with pytest.raises(ValueError, match="in use by another search"):
        DesignSearch(str(CONFIG), out, budget_evals=4, seed=9, resume=True)
    del first
    with pytest.raises(ValueError, match="empty path"):
        DesignSearch(str(CONFIG), "", budget_evals=4, seed=9)
    (tmp_path / "a-file").write_text("x")
    with pytest.raises(ValueError, match="not a directory"):
        DesignSearch(str(CONFIG), str(tmp_path / "a-file"), budget_evals=4, seed=9)


def test_a_candidate_outside_the_search_box_is_refused(tmp_path):
    import json

    search = DesignSearch(str(CONFIG), str(tmp_path / "run"), budget_evals=4, seed=9)
    problem = SearchProblem(search.problem)
    search.tell([problem.evaluate(c) for c in search.ask()])
    candidate = json.loads(search.ask()[0])
    candidate["x"][0] = 1.5
    with pytest.raises(ValueError, match=r"candidate x\[0\] = 1.5: expected a number in \[0, 1\]"):
        problem.evaluate(json.dumps(candidate))


def test_errors_name_the_python_arguments_too(tmp_path):
    out = str(tmp_path / "run")
    search = DesignSearch(str(CONFIG), out, budget_evals=4, seed=9)
    problem = SearchProblem(search.problem)
    search.tell([problem.evaluate(c) for c in search.ask()])
    del search
    with pytest.raises(ValueError, match="already holds evaluations") as e:
        DesignSearch(str(CONFIG), out, budget_evals=4, seed=9)
    assert "resume=True" in str(e.value) and "(out)" in str(e.value)
    with pytest.raises(ValueError, match=r"\(resume=True\): no run to continue"):
        DesignSearch(str(CONFIG), str(tmp_path / "none"), resume=True)


def test_close_and_with_release_the_directory(tmp_path):
    out = str(tmp_path / "run")
    search = DesignSearch(str(CONFIG), out, budget_evals=4, seed=9)
    search.close()
    with pytest.raises(RuntimeError, match="finished \\(or closed\\)"):
        search.ask()
    # Rebinding the name (the old object still alive while the new one opens) works
    # once the old one is closed; a `with` block closes on leaving.
    with DesignSearch(str(CONFIG), out, budget_evals=4, seed=9, resume=True) as s:
        assert s.ask()
    search = DesignSearch(str(CONFIG), out, budget_evals=4, seed=9, resume=True)
    assert search.ask()


def ended_search_whose_finish_failed(out):
    """A search run to its end in `out` whose finish() raised OSError: an output that
    cannot be written (a directory where pareto.csv goes, removed again afterwards)."""
    search = DesignSearch(str(CONFIG), str(out), budget_evals=4, seed=9)
    problem = SearchProblem(search.problem)
    while candidates := search.ask():
        search.tell([problem.evaluate(c) for c in candidates])
    (out / "pareto.csv").mkdir()
    with pytest.raises(OSError):
        search.finish("test", 1)
    (out / "pareto.csv").rmdir()
    return search


def test_the_directory_stays_locked_until_the_outputs_are_written(tmp_path):
    out = tmp_path / "run"
    # The directory stays the search's until it writes its outputs or closes.
    search = ended_search_whose_finish_failed(out)
    with pytest.raises(ValueError, match="in use by another search"):
        DesignSearch(str(CONFIG), str(out), budget_evals=4, seed=9, resume=True)
    assert search.finish("test", 1)["candidates"] == 4
    # Written: released (the object is still alive), and not written again.
    with DesignSearch(str(CONFIG), str(out), budget_evals=4, seed=9, resume=True) as s:
        assert s.ask() == []
        with pytest.raises(RuntimeError, match="written the outputs already"):
            search.finish("test", 1)
    search.close()


def test_finish_after_close_writes_nothing(tmp_path):
    out = tmp_path / "run"
    search = ended_search_whose_finish_failed(out)
    search.close()
    # Another search holds the directory now: the closed one must not write into it.
    with DesignSearch(str(CONFIG), str(out), budget_evals=4, seed=9, resume=True):
        with pytest.raises(RuntimeError, match="closed"):
            search.finish("test", 1)
    assert not (out / "report.md").exists()


@pytest.mark.parametrize(
    "flag, value",
    [("--seed", "-1"), ("--budget-evals", "-1"), ("--budget-evals", "0"), ("--seed", str(2**64))],
)
def test_the_command_line_refuses_out_of_range_counts_as_bad_input(tmp_path, capsys, flag, value):
    from tdpcr.optim import main

    # Exit 2 with a message, before any search (a negative seed raised OverflowError).
    with pytest.raises(SystemExit) as e:
        main([str(CONFIG), "--out", str(tmp_path / "run"), flag, value])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {flag}: {value}: expected" in err, err
    assert not (tmp_path / "run").exists()
