"""What automatic finding looks for (``--subject auto|animal|person|object``) and the
"unsure" note: exact masks on small synthetic scenes (:mod:`jeanscv.subject.kinds`),
a pet beside its owner (:func:`testkit.synthetic_photos.pet_beside_owner`) through the
API, the command line and the server."""

from __future__ import annotations

import io
import json
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import jeanscv
from jeanscv.errors import JeansError
from jeanscv.subject.consensus import Candidate
from jeanscv.subject.kinds import KindCues, choose_kind, split_pieces
from testkit.synthetic_photos import iou, pet_beside_owner

pytestmark = pytest.mark.usefixtures("cut_once")  # the same photos' hypotheses, cut once (conftest.py)


@cache
def scene():
    return pet_beside_owner()


@cache
def found(subject: str):
    return jeanscv.extract_silhouette(scene().image, subject=subject)


# ------------------------------------------------------------------ exact masks


def _cues(shape, people=None, detail=None) -> KindCues:
    """Cues with a given people map and texture map (no detector, no photo)."""
    cues = KindCues(np.zeros((*shape, 3), np.uint8), np.zeros((*shape, 3), np.uint8))
    cues.__dict__["people"] = np.zeros(shape, bool) if people is None else people
    cues.__dict__["detail"] = np.ones(shape, np.float32) if detail is None else detail
    return cues


def _scene_masks():
    """A 40x60 scene: a tall figure (rows 5-34, columns 5-14) in a person box, and a
    round-ish furry square (rows 20-33, columns 35-50) whose texture is 8 times its
    surroundings'."""
    shape = (40, 60)
    figure = np.zeros(shape, bool)
    figure[5:35, 5:15] = True
    pet = np.zeros(shape, bool)
    pet[20:34, 35:51] = True
    people = np.zeros(shape, bool)
    people[3:37, 3:17] = True
    detail = np.ones(shape, np.float32)
    detail[pet] = 15.0  # (15 + 1) / (1 + 1) = 8
    return figure, pet, _cues(shape, people, detail)


def test_pieces_of_a_mask_largest_first_specks_dropped():
    mask = np.zeros((40, 60), bool)
    mask[2:12, 2:12] = True  # 100 pixels
    mask[20:30, 30:36] = True  # 60
    mask[35:38, 50:53] = True  # 9: under a tenth of the largest, a speck
    pieces = split_pieces(mask)
    assert [int(p.sum()) for p in pieces] == [100, 60]
    assert pieces[0][2:12, 2:12].all() and not pieces[0][20:30, 30:36].any()
    assert split_pieces(np.zeros((5, 5), bool)) == []


def test_a_person_and_an_animal_the_animal_unless_asked():
    figure, pet, cues = _scene_masks()
    both = Candidate("grabcut", figure | pet, score=0.8)
    judged = {p.kind: p for p in cues.pieces("grabcut", both.mask, both.score)}
    assert set(judged) == {"person", "animal"}
    assert judged["person"].person == 1.0 and judged["animal"].fur == 8.0
    assert judged["person"].upright == 3.0  # 30 rows by 10 columns

    auto = choose_kind(cues, [both], "grabcut", "auto")
    assert auto.kind == "animal" and np.array_equal(auto.mask, pet) and auto.found
    person = choose_kind(cues, [both], "grabcut", "person")
    assert person.kind == "person" and np.array_equal(person.mask, figure)
    assert choose_kind(cues, [both], "grabcut", "object").mask is None  # the winner as it is


def test_auto_keeps_a_winner_with_no_person_in_it():
    figure, pet, cues = _scene_masks()
    cues.__dict__["people"] = np.zeros(pet.shape, bool)
    cues.__dict__["detail"] = np.ones(pet.shape, np.float32)  # nothing furry
    lying = np.zeros(pet.shape, bool)
    lying[25:35, 5:35] = True  # wide and plain: no standing figure, no person box
    choice = choose_kind(cues, [Candidate("rect", lying, score=0.5)], "rect", "auto")
    assert choice.mask is None and choice.kind == "object" and choice.found


def test_a_person_asked_for_and_none_found_is_a_guess():
    _, pet, cues = _scene_masks()
    choice = choose_kind(cues, [Candidate("rect", pet, score=0.5)], "rect", "person")
    assert choice.mask is None and not choice.found and "no person" in choice.reason


def test_animal_from_another_hypothesis_when_the_winner_is_the_person():
    figure, pet, cues = _scene_masks()
    winner = Candidate("grabcut", figure, score=0.8)
    other = Candidate("rect", pet, score=0.5)  # at least half the winner's score
    choice = choose_kind(cues, [winner, other], "grabcut", "auto")
    assert np.array_equal(choice.mask, pet) and choice.pieces[0].source == "rect"
    weak = Candidate("rect", pet, score=0.3)  # under half: auto keeps the person
    assert choose_kind(cues, [winner, weak], "grabcut", "auto").mask is None
    assert np.array_equal(choose_kind(cues, [winner, weak], "grabcut", "animal").mask, pet)


def test_several_animals_one_or_all():
    shape = (40, 80)
    big, small = np.zeros(shape, bool), np.zeros(shape, bool)
    big[10:30, 5:35] = True
    small[15:30, 50:70] = True
    detail = np.ones(shape, np.float32)
    detail[big | small] = 9.0
    cues = _cues(shape, detail=detail)
    both = Candidate("grabcut", big | small, score=0.7)
    one = choose_kind(cues, [both], "grabcut", "animal")
    assert np.array_equal(one.mask, big)  # the most prominent
    every = choose_kind(cues, [both], "grabcut", "animal", several=True)
    assert np.array_equal(every.mask, big | small) and len(every.pieces) == 2


def test_uncertain_says_why():
    pick = Candidate("rect", np.zeros((4, 4), bool), consensus=0.9, agreement=0.9, side_contact=0.0)
    assert not pick.uncertain and pick.doubts == []
    pick.consensus, pick.agreement, pick.side_contact = 0.6, 0.3, 0.2
    assert pick.uncertain and len(pick.doubts) == 3


# ------------------------------------------------------------------ a photo


def test_pet_beside_its_owner_auto_takes_the_pet():
    owner, pet = scene().masks
    auto = found("auto")
    assert auto.details["kind"] == "animal" and auto.details["subject"] == "auto"
    assert iou(auto.mask >= 0.5, pet) >= 0.9
    assert not auto.details["uncertain"] and auto.details["doubts"] == []


def test_pet_beside_its_owner_person_and_object():
    owner, pet = scene().masks
    person = found("person")
    assert person.details["kind"] == "person" and iou(person.mask >= 0.5, owner) >= 0.9
    # object: the most salient thing, whatever it is (here both together, as before)
    assert iou(found("object").mask >= 0.5, owner | pet) >= 0.9


def test_unknown_subject_is_one_clear_error():
    with pytest.raises(JeansError, match="unknown subject 'unicorn'"):
        jeanscv.extract_silhouette(scene().image, subject="unicorn")
    with pytest.raises(JeansError, match="unknown subject 'unicorn'"):
        jeanscv.JeansOptions(subject="unicorn")


def test_command_line_subject_report_and_batch_summary(tmp_path, run_cli):
    """A folder of two: the owner cut by the left side (unsure: the person found runs
    along that side) and the whole scene (sure); --subject person dresses the owner."""
    folder = tmp_path / "photos"
    folder.mkdir()
    Image.fromarray(np.ascontiguousarray(scene().image[:, 150:])).save(folder / "a.png")
    Image.fromarray(scene().image).save(folder / "b.png")
    report, out = tmp_path / "report.jsonl", tmp_path / "out"
    result = run_cli(
        folder,
        *("--subject", "person", "--detector", "none"),  # the classical kind cues on drawn shapes
        *("--json", "--report", report, "-o", out, "--iterations", "5", "-j", "1"),
    )
    assert result.exit_code == 0, result.stderr
    assert f"jeanscv: 1 of 2 may have the wrong subject: `jeanscv serve {folder}/` shows them first" in result.stderr
    assert "a.png: note: unsure which thing is the subject (" in result.stderr
    lines = {Path(json.loads(x)["input"]).name: json.loads(x) for x in report.read_text().splitlines()}
    assert lines["a.png"]["uncertain"] is True and lines["b.png"]["uncertain"] is False
    sidecar = json.loads((out / "b.jeans.json").read_text())
    assert sidecar["subject"]["subject"] == "person" and sidecar["subject"]["kind"] == "person"
    assert sidecar["subject"]["uncertain"] is False and sidecar["subject"]["doubts"] == []
    assert run_cli(folder / "b.png", "--subject", "unicorn").exit_code == 2


def test_server_takes_the_subject_field(make_client):
    pytest.importorskip("starlette")
    client = make_client()
    buffer = io.BytesIO()
    Image.fromarray(scene().image).save(buffer, "PNG")
    data = buffer.getvalue()
    answer = client.post("/api/photos", files={"file": ("a.png", data)}, data={"subject": "person"})
    assert answer.status_code == 200, answer.text
    assert answer.json()["summary"]["uncertain"] is False
    refused = client.post("/api/photos", files={"file": ("a.png", data)}, data={"subject": "unicorn"})
    assert refused.status_code == 422 and "unknown subject" in refused.json()["error"]


def test_folder_listing_flags_the_unsure_once_known(make_client, tmp_path):
    pytest.importorskip("starlette")
    Image.fromarray(np.ascontiguousarray(scene().image[:, 150:])).save(tmp_path / "a.png")
    Image.fromarray(scene().image).save(tmp_path / "b.png")
    client = make_client(folder=tmp_path)
    items = client.get("/api/folder").json()["items"]
    assert [item["uncertain"] for item in items] == [None, None]
    for item in items:
        assert client.post(item["thumb"]).status_code == 200
    assert [item["uncertain"] for item in client.get("/api/folder").json()["items"]] == [True, False]


def test_two_pets_on_a_sofa_one_pair_or_a_pair_each():
    from jeanscv.subject.photo import SharedHypotheses
    from testkit.synthetic_photos import two_pets_on_sofa

    photo = two_pets_on_sofa()
    left, right = photo.masks
    shared = SharedHypotheses()  # the hypotheses cut once for both calls
    (one,) = jeanscv.extract_silhouettes(photo.image, shared=shared)
    assert one.details["kind"] == "animal" and iou(one.mask >= 0.5, left) >= 0.9  # the larger one
    every = jeanscv.extract_silhouettes(photo.image, objects="all", shared=shared)
    assert [round(iou(s.mask >= 0.5, m), 1) >= 0.9 for s, m in zip(every, (left, right))] == [True, True]
    assert all(s.details["subject"] == "auto" and s.details["uncertain"] is False for s in every)


def test_the_unsure_count_comes_before_the_summary_and_not_when_quiet():
    from jeanscv_cli.progress import Progress
    from jeanscv_cli.worker import Outcome

    for quiet in (False, True):
        stream = io.StringIO()
        progress = Progress(3, quiet=quiet, stream=stream, tty=False)
        progress.serve_hint = "jeanscv serve photos/"
        progress.finish(Outcome(0, "a.png", "ok", "a.jeans.png", info={"uncertain": True}))
        progress.finish(Outcome(1, "b.png", "ok", "b.jeans.png", info={"uncertain": False}))
        progress.finish(Outcome(2, "c.png", "ok", "c.jeans.png"))  # a drawing: nothing to doubt
        summary = progress.summary()
        lines = stream.getvalue().splitlines()
        if quiet:
            assert lines == []
        else:
            unsure = "jeanscv: 1 of 3 may have the wrong subject: `jeanscv serve photos/` shows them first"
            assert lines[-2:] == [unsure, summary] and summary.startswith("3 ok, 0 failed, 0 skipped in ")


@pytest.mark.parametrize("shape", [(96, 128), (200, 40), (128, 64)])
def test_the_people_detector_skips_copies_smaller_than_its_window(shape):
    """OpenCV's HOG detector crashed the process on a 128x96 photo (smaller than its
    64x128 window); a copy of exactly the window's size is searched."""

    rgb = np.full((*shape, 3), 128, np.uint8)
    people = KindCues(rgb, rgb).people
    assert people.shape == shape and not people.any()
