"""Silent acceptances of the effect loader turned into one-line errors (issue 36's second bad-input campaign).

Before the fix an effects folder that could not be read was listed as empty (Path.glob swallows the error),
and EHAS_TRUSTED_EFFECTS naming a missing file, or a trust list naming a missing folder, meant "no trust
list" without a word; an EHAS_EFFECTS_PATH error did not name the variable the user may have forgotten.
"""
from __future__ import annotations

import json
import os
import shutil

import pytest

from ehas_env.physics.effects import loading

EFFECT = "raise SystemExit('never imported: the folder cannot be listed')\n"


def test_an_unreadable_effects_folder_is_refused_not_listed_empty(tmp_path, monkeypatch):
    folder = tmp_path / "effects"
    folder.mkdir()
    (folder / "probe.py").write_text(EFFECT)
    real = os.listdir

    def listdir(path="."):
        if os.fspath(path) == os.fspath(folder):
            raise PermissionError(13, "Permission denied", os.fspath(path))
        return real(path)

    monkeypatch.setattr(os, "listdir", listdir)  # root reads any folder: the refusal of the OS, simulated
    with pytest.raises(ValueError) as exc:
        loading.load_effects_path(folder)
    assert str(exc.value) == (f"effects path {folder}: the folder cannot be read (Permission denied); its effect "
                              "files would be missing")


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root reads a folder of mode 000")
def test_an_unreadable_effects_folder_for_real(tmp_path):
    folder = tmp_path / "effects"
    folder.mkdir()
    folder.chmod(0)
    try:
        with pytest.raises(ValueError, match="cannot be read"):
            loading.load_effects_path(folder)
    finally:
        folder.chmod(0o755)


def test_an_empty_readable_folder_is_still_fine(tmp_path):
    (tmp_path / "empty").mkdir()
    loading.load_effects_path(tmp_path / "empty")  # nothing to load, nothing wrong


def test_the_effects_path_variable_is_named_in_its_error(tmp_path, monkeypatch):
    monkeypatch.setenv(loading.ENV_VAR, str(tmp_path / "nope"))
    with pytest.raises(ValueError) as exc:
        loading.load_external_effects()
    assert str(exc.value).startswith(f"EHAS_EFFECTS_PATH: effects path {tmp_path / 'nope'} does not exist")


def test_a_trust_list_variable_naming_a_missing_file_is_refused(tmp_path, monkeypatch):
    monkeypatch.delenv(loading.ENV_VAR, raising=False)
    monkeypatch.setenv(loading.TRUST_ENV, str(tmp_path / "trusted.json"))
    with pytest.raises(ValueError, match=r"EHAS_TRUSTED_EFFECTS names .*trusted.json, which does not exist"):
        loading.trusted_folders()  # was: [] (no trust list), silently
    with pytest.raises(ValueError, match="EHAS_TRUSTED_EFFECTS"):
        loading.load_external_effects()  # said at start-up, as a missing EHAS_EFFECTS_PATH is


def test_a_trust_list_naming_a_missing_folder_is_refused(tmp_path, monkeypatch):
    trust = tmp_path / "trusted.json"
    trust.write_text(json.dumps({"format": "ehas-trusted-effects", "version": 1,
                                 "folders": [str(tmp_path / "gone")]}))
    monkeypatch.setenv(loading.TRUST_ENV, str(trust))
    with pytest.raises(ValueError, match=r"trust list .*trusted.json: folder .*gone does not exist"):
        loading.trusted_folders()


def test_a_trust_list_that_exists_is_read(tmp_path, monkeypatch):
    """The checks refuse only what is missing: an existing trust list's folders are returned as before."""
    folder = tmp_path / "mine"
    folder.mkdir()
    trust = tmp_path / "trusted.json"
    trust.write_text(json.dumps({"format": "ehas-trusted-effects", "version": 1, "folders": [str(folder)]}))
    monkeypatch.setenv(loading.TRUST_ENV, str(trust))
    assert loading.trusted_folders() == [folder]
    shutil.rmtree(folder)
    with pytest.raises(ValueError, match="does not exist"):
        loading.trusted_folders()
