"""hoap-actions demo: several policies side by side, the models option, the filmed episode."""

from __future__ import annotations

from hoap_actions.apps.cli import main


def test_the_cli_refuses_models_without_the_phmm_policy(capsys):
    assert main(["demo", "--policy", "scripted", "--models", "somewhere", "--episodes", "1"]) == 2
    assert "--models is for the phmm policy" in capsys.readouterr().err


def test_the_cli_films_the_chosen_episode(tmp_path, capsys):
    assert main(["demo", "--policy", "scripted", "--episodes", "2", "--seed", "1000", "--film", "1",
                 "--snapshot", str(tmp_path / "s.png")]) == 0
    assert "picture of episode 1 (scripted, seed 1001)" in capsys.readouterr().out
    assert (tmp_path / "s.png").is_file()
    assert main(["demo", "--policy", "scripted", "--episodes", "2", "--film", "2"]) == 2
    assert "--film 2 is past the last episode" in capsys.readouterr().err


def test_a_missing_models_directory_is_one_line_before_any_worker_starts(tmp_path, capsys):
    assert main(["demo", "--policy", "phmm", "--models", str(tmp_path / "none"), "--episodes", "2",
                 "--workers", "2"]) == 2
    assert "no models directory" in capsys.readouterr().err


def test_the_json_is_the_same_file_whatever_the_number_of_workers(tmp_path, capsys):
    outputs = []
    for workers in ("1", "2"):
        out = tmp_path / f"w{workers}.json"
        assert main(["demo", "--policy", "scripted", "--episodes", "3", "--seed", "1000", "--workers", workers,
                     "--json", str(out)]) == 0
        outputs.append(out.read_bytes())
    assert outputs[0] == outputs[1]
    assert b"wall_s" not in outputs[0] and b'"success": true' in outputs[0]
    assert "mean episode" in capsys.readouterr().out
