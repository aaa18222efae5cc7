from experiments.compare_methods import main as compare_main


def test_compare_methods_quick(tmp_path, capsys):
    assert compare_main(["--quick", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "table.md").read_text()
    assert text.count("\n| `") == 7  # one row per method
    assert "`tl`" in capsys.readouterr().out
