from experiments.compare_methods import main as compare_main


def test_compare_methods_quick(tmp_path, capsys):
    assert compare_main(["--quick", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "table.md").read_text()
    assert text.count("\n| `") == 7  # one row per method
    assert "`tl`" in capsys.readouterr().out


def test_evaluate_all_quick(tmp_path):
    from experiments.evaluate_all import main as evaluate_all

    assert evaluate_all(["--quick", "--out", str(tmp_path)]) == 0
    matrix = (tmp_path / "matrix.md").read_text()
    assert "| fis |" in matrix and "paper" in matrix and "nominal" in matrix
    assert (tmp_path / "paper" / "results.json").exists()
