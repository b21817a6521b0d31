"""``jeanscv serve``: every endpoint through Starlette's test client, the server's
safety (Host, Origin, size caps, ids, folder confinement, a full pool) and folder mode."""

from __future__ import annotations

import io
import json
import threading
from functools import cache
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import write_silhouette_png
from PIL import Image
from test_bad_inputs import BAD_FILES
from test_objects import inside_point, share_on

from testkit.synthetic_photos import two_objects

starlette = pytest.importorskip("starlette")

from jeanscv.subject.clicks import Clicks, read_clicks, sidecar_path  # noqa: E402
from jeanscv_cli.serve import engine, found  # noqa: E402

BASE = "http://127.0.0.1:8000"

pytestmark = pytest.mark.usefixtures("cut_once")  # the same photos' hypotheses, cut once (conftest.py)


@cache
def scene():
    """The dog and its owner (800x500), made once for every test that uses it: read-only."""
    photo = two_objects()
    for array in (photo.image, *photo.masks):
        array.flags.writeable = False
    return photo


def png_bytes(pixels: np.ndarray, compress_level: int = 6) -> bytes:
    """``pixels`` as a PNG file (``compress_level`` 1: four times faster, a little larger)."""
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, "PNG", compress_level=compress_level)
    return buffer.getvalue()


@pytest.fixture
def client(make_client):
    return make_client()


def upload(client, name: str, data: bytes, **fields):
    return client.post("/api/photos", files={"file": (name, data, "application/octet-stream")}, data=fields)


def server_temp(client) -> Path:
    return client.app.app.state.jeanscv.tmp


# ------------------------------------------------------------------ the page


def test_page_and_static_files(client):
    page = client.get("/")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert b'type="module" src="/static/app.js"' in page.content and b'href="/static/style.css"' in page.content
    # Every ES module beside app.js is served as JavaScript (the server serves a fixed list).
    scripts = [f"/static/{path.name}" for path in sorted((Path(engine.__file__).parent / "static").glob("*.js"))]
    assert len(scripts) > 1
    for path, media in [*((script, "text/javascript") for script in scripts), ("/static/style.css", "text/css")]:
        response = client.get(path)
        assert response.status_code == 200 and response.headers["content-type"].startswith(media)
    # Nothing from another host: no absolute URL in the page, its scripts or its style.
    for path in ("/", *scripts, "/static/style.css"):
        text = client.get(path).text
        assert "http://" not in text.replace("http://www.w3.org/2000/svg", "") and "https://" not in text
    # The whole page, as sent, stays light (no build step, nothing minified).
    assert sum(len(client.get(path).content) for path in ("/", *scripts, "/static/style.css")) < 300_000
    csp = page.headers["content-security-policy"]
    assert "default-src 'none'" in csp and "connect-src 'self'" in csp
    assert page.headers["x-content-type-options"] == "nosniff"
    assert "access-control-allow-origin" not in page.headers


def test_options(client):
    options = client.get("/api/options").json()
    assert "jeans" in options["garments"] and options["styles"] == ["denim", "flat"]
    assert options["postures"] == ["upright", "any"] and options["folder"] is False


# ------------------------------------------------------------------ one photo


def test_good_photo_then_clicks_then_downloads(client):
    photo = scene()
    owner, dog = photo.masks
    answer = upload(client, "two.png", png_bytes(photo.image))
    assert answer.status_code == 200, answer.text
    first = answer.json()
    assert (first["width"], first["height"]) == (800, 500) and first["kind"] == "photo"
    assert first["clicks"] is False and first["objects"]
    preview = client.get(first["preview"])
    assert preview.headers["content-type"] == "image/jpeg"
    with Image.open(io.BytesIO(preview.content)) as image:
        assert image.size == (800, 500)  # long side under the preview's 1280: full size
    original = client.get(f"/api/photos/{first['photo']}/original")
    assert original.status_code == 200 and original.content != preview.content

    # A click on the dog: the jeans go onto it, its outline is the dog's.
    point = inside_point(dog)
    clicked = client.post(
        f"/api/photos/{first['photo']}/render",
        json={"objects": [{"positive": [point], "negative": []}], "options": {"style": "flat"}},
    )
    assert clicked.status_code == 200, clicked.text
    second = clicked.json()
    assert second["clicks"] is True and len(second["objects"]) == 1
    assert share_on(second["objects"][0]["jeans"], dog) > 0.9
    trajectory = np.asarray(second["objects"][0]["trajectory"])
    assert trajectory.shape == (engine.ANIMATION_FRAMES, 8, 2)
    np.testing.assert_allclose(trajectory[-1], second["objects"][0]["jeans"], atol=0.06)

    # Two objects: the owner too, each with its garment.
    both = client.post(
        f"/api/photos/{first['photo']}/render",
        json={"objects": [{"positive": [point]}, {"positive": [inside_point(owner)]}]},
    ).json()
    assert [share_on(o["jeans"], m) > 0.9 for o, m in zip(both["objects"], (dog, owner))] == [True, True]

    downloads = second["downloads"]
    image = client.get(downloads["image"])
    assert image.headers["content-disposition"] == 'attachment; filename="two.jeans.png"'
    with Image.open(io.BytesIO(image.content)) as full:
        assert full.size == (800, 500)
        pixels = np.asarray(full.convert("RGB"))
    # Flat style: the paper's blue on the dog only.
    blue = (pixels[..., 2] > 200) & (pixels[..., 0] < 40) & (pixels[..., 1] < 40)
    assert blue[dog].mean() > 0.1 and not blue[owner].any()

    meme = client.get(downloads["meme"], params={"top": "how would a dog", "bottom": "wear jeans", "side_by_side": "1"})
    with Image.open(io.BytesIO(meme.content)) as picture:
        assert picture.size == (1600, 500)
        top_band = np.asarray(picture.convert("RGB"))[:40, 800:]
    assert (top_band.min(axis=-1) > 240).mean() > 0.02  # white caption letters

    report = json.loads(client.get(downloads["json"]).content)
    assert report["objects"][0]["method"] == "clicks" and report["image_size"] == [800, 500]
    assert client.get(downloads["svg"]).content.startswith(b"<?xml")
    gif = client.get(downloads["gif"])
    assert gif.headers["content-type"] == "image/gif" and gif.content[:6] == b"GIF89a"
    with Image.open(io.BytesIO(gif.content)) as animation:  # the preview's size (this photo's own), every step
        assert animation.size == (800, 500) and animation.n_frames > 10
    clicks = client.get(downloads["clicks"])
    assert clicks.headers["content-disposition"] == 'attachment; filename="two.clicks.json"'
    replay = Clicks.single([point], image_size=(800, 500))
    from jeanscv.subject.clicks import loads_clicks

    assert loads_clicks(clicks.content) == replay
    # The automatic result has no clicks file to give.
    assert client.get(first["downloads"]["clicks"]).status_code == 422
    assert list(server_temp(client).iterdir()) == []


@pytest.mark.fresh_cuts  # counts the cuts
def test_auto_and_the_click_session_cut_the_hypotheses_once(client, monkeypatch):
    from jeanscv.subject import photo as segmentation

    cuts = []
    hypotheses = segmentation.hypotheses
    monkeypatch.setattr(segmentation, "hypotheses", lambda *args: cuts.append(1) or hypotheses(*args))
    first = upload(client, "two.png", png_bytes(scene().image)).json()
    point = inside_point(scene().masks[1])
    clicked = client.post(f"/api/photos/{first['photo']}/render", json={"objects": [{"positive": [point]}]})
    assert clicked.status_code == 200 and len(cuts) == 1


def test_nothing_found_is_an_answer_not_a_refusal(client):
    """Issue 49: a click or a box on plain background was refused 422, and the browser
    logged every such click as a failed request. It is a normal answer now, 200 with
    ``nothing`` (the reason the page shows) and no result; a bad body stays 422."""
    first = upload(client, "two.png", png_bytes(scene().image)).json()
    url = f"/api/photos/{first['photo']}/render"
    for objects, words in (
        ([{"positive": [[20.5, 20.5]]}], "two.png: nothing clear there: click inside the subject"),
        ([{"box": [5, 5, 40, 40]}], "two.png: nothing found in that box: click inside the subject"),
    ):
        answer = client.post(url, json={"objects": objects})
        assert answer.status_code == 200, answer.text
        assert answer.json() == {"photo": first["photo"], "name": "two.png", "kind": "photo", "nothing": words}
    assert client.post(url, content=b"{").status_code == 422  # a bad request is still refused


def test_the_caption_layer_says_how_each_caption_was_fitted(client):
    """The caption picture's answer carries each caption's fit (lines, font size, cut):
    a long caption takes more lines (it was cut to three), one too long for a small
    picture is cut and says so."""
    first = upload(client, "two.png", png_bytes(scene().image)).json()
    url = f"/api/results/{first['result']}/captions"
    long = "how would a dog wear jeans if it had two legs like ours and a tail to fit through them " * 2
    layer = client.get(url, params={"top": long, "bottom": "wear jeans?"})
    assert layer.status_code == 200 and layer.headers["content-type"] == "image/png"
    fits = json.loads(layer.headers["x-caption-fit"])
    assert fits["top"]["lines"] > 3 and not fits["top"]["cut"]
    assert (fits["bottom"]["lines"], fits["bottom"]["cut"]) == (1, False)
    small = upload(client, "small.png", png_bytes(scene().image[::5, ::5].copy())).json()
    fits = json.loads(
        client.get(f"/api/results/{small['result']}/captions", params={"top": long}).headers["x-caption-fit"]
    )
    assert fits == {"top": {"lines": 3, "size": 8, "cut": True}}


def test_a_negative_click_alone_takes_that_away_from_the_automatic_subject(client):
    """A negative click alone edits the automatic subject the page shows. On the dog and
    its owner the detector sees the dog, and the page shows the dog: a negative click on
    its head leaves the rest of the dog (classical finding's subject, the owner and the
    dog as one, would have left the owner: what the page did not show). Asked for the
    most salient thing (classical finding: the owner and the dog as one), a negative
    click on the owner leaves the dog."""
    owner, dog = scene().masks
    first = upload(client, "two.png", png_bytes(scene().image)).json()
    assert first["summary"]["method"] == "detector" and first["summary"]["detection"]["class"] == "dog"
    (automatic,) = first["objects"]
    ax0, ay0, aw, ah = automatic["box"]
    dx0, dy0, dx1, dy1 = _box(dog)
    assert max(abs(a - b) for a, b in zip((ax0, ay0, ax0 + aw, ay0 + ah), (dx0, dy0, dx1, dy1))) <= 8  # the dog
    head = (385.0, 205.0)
    assert dog[int(head[1]), int(head[0])]
    answer = client.post(f"/api/photos/{first['photo']}/render", json={"objects": [{"negative": [head]}]})
    assert answer.status_code == 200, answer.text
    (found,) = answer.json()["objects"]
    x0, y0, w, h = found["box"]
    assert x0 > head[0] + 5 and x0 > _box(owner)[2]  # the head gone, and no owner brought in
    assert abs(x0 + w - (ax0 + aw)) <= 8 and abs(y0 + h - (ay0 + ah)) <= 8  # the rest of the dog as shown
    assert share_on(found["jeans"], dog) > 0.9

    # Classical finding's subject: the owner and the dog; minus the owner, the dog.
    first = upload(client, "two.png", png_bytes(scene().image), subject="object").json()
    assert first["summary"]["method"] != "detector" and first["summary"]["detection"] is None
    answer = client.post(
        f"/api/photos/{first['photo']}/render", json={"objects": [{"positive": [], "negative": [inside_point(owner)]}]}
    )
    assert answer.status_code == 200, answer.text
    (found,) = answer.json()["objects"]
    (automatic,) = first["objects"]  # owner and dog, as one subject
    x0, y0, w, h = found["box"]
    ax0, ay0, aw, ah = automatic["box"]
    assert ax0 < _box(owner)[2]  # auto had the owner
    # The dog as auto had it (auto may miss its tail's end), the owner gone.
    expected = (dx0, dy0, min(dx1, ax0 + aw), min(dy1, ay0 + ah))
    assert max(abs(a - b) for a, b in zip((x0, y0, x0 + w, y0 + h), expected)) <= 8, (found["box"], expected)


def two_cats() -> np.ndarray:
    """The bundled cat beside its mirror image, a grey gap between them (962x300): two
    animals that the shipped detector finds (no sample photo has two), both cats; it
    dresses the right one (0.60), the left one scores 0.51."""
    with Image.open(Path(__file__).resolve().parents[1] / "sample_images" / "cat.jpg") as opened:
        cat = np.asarray(opened.convert("RGB"))
    return np.concatenate([cat, np.full((cat.shape[0], 60, 3), 235, np.uint8), cat[:, ::-1]], axis=1)


def test_the_answer_names_the_detected_animals_and_a_box_of_one_dresses_it(client):
    """The photo's JSON carries the detected animals (class, score, box in the photo's
    pixels, which one is dressed); a render with an animal's box dresses that animal."""
    first = upload(client, "two.png", png_bytes(scene().image)).json()
    (dog,) = first["detections"]  # the owner is a person: no animal to offer
    assert dog["class"] == "dog" and dog["dressed"] is True and 0.5 < dog["score"] < 0.7
    assert max(abs(a - b) for a, b in zip(dog["box"], _box(scene().masks[1]))) <= 16

    cats = upload(client, "cats.png", png_bytes(two_cats())).json()
    assert [(d["class"], d["score"], d["dressed"]) for d in cats["detections"]] == [
        ("cat", 0.602, True),
        ("cat", 0.509, False),
    ]
    assert cats["summary"]["detection"] == {"class": "cat", "score": 0.602}
    right, left = (d["box"] for d in cats["detections"])
    assert right[0] > 481 > left[2]  # one cat on each side of the gap
    x, _, w, _ = cats["objects"][0]["box"]
    assert x >= right[0] - 2 and x + w <= right[2] + 2  # the right cat wears the jeans
    chosen = client.post(f"/api/photos/{cats['photo']}/render", json={"objects": [{"box": left}]})
    assert chosen.status_code == 200, chosen.text
    answer = chosen.json()
    assert [d["dressed"] for d in answer["detections"]] == [False, True]
    x, _, w, _ = answer["objects"][0]["box"]
    assert x >= left[0] - 2 and x + w <= left[2] + 2 and answer["summary"]["detection"] is None
    # A click (no box) on the right cat starts from its detected box: the whole cat, not a
    # part of its face (without the detector: its nose and mouth, a sixth of the box).
    clicked = client.post(f"/api/photos/{cats['photo']}/render", json={"objects": [{"positive": [[750, 150]]}]})
    x, y, w, h = clicked.json()["objects"][0]["box"]
    assert w * h > 0.5 * (right[2] - right[0]) * (right[3] - right[1])
    assert x >= right[0] - 2 and x + w <= right[2] + 2
    assert [d["dressed"] for d in clicked.json()["detections"]] == [True, False]
    # A box drawn round it (not the detection's own) dresses it: the cut lies in its box and fills it.
    drawn = client.post(f"/api/photos/{cats['photo']}/render", json={"objects": [{"box": [530, 0, 962, 300]}]})
    assert [d["dressed"] for d in drawn.json()["detections"]] == [True, False]


def test_name_it_names_the_dressed_animal_where_the_detector_is_sure(client, tmp_path):
    """The answer's caption is --top auto's: the class of what wears the jeans, also of an
    animal chosen on the page; what no sure detection wears is "this"."""
    cats = upload(client, "cats.png", png_bytes(two_cats())).json()
    assert cats["caption"] == ["how would a cat", "wear jeans?"]  # cat 0.60, no other class on its box
    other = next(d for d in cats["detections"] if not d["dressed"])  # cat 0.51
    chosen = client.post(f"/api/photos/{cats['photo']}/render", json={"objects": [{"box": other["box"]}]})
    assert chosen.status_code == 200, chosen.text
    assert chosen.json()["caption"] == ["how would a cat", "wear jeans?"]
    # A click on a cat dresses the cat its detected box holds: named too.
    clicked = client.post(f"/api/photos/{cats['photo']}/render", json={"objects": [{"positive": [[750, 150]]}]})
    assert clicked.json()["caption"] == ["how would a cat", "wear jeans?"]
    drawing = upload(client, "person.png", write_silhouette_png(tmp_path / "person.png").read_bytes()).json()
    assert drawing["caption"] == ["how would this", "wear jeans?"]


def test_detections_are_in_the_photos_pixels_as_displayed():
    """Boxes go to the page in pixels of the photo as displayed, also where it was
    decoded at another size (a RAW file at half size): scaled from the decoded copy."""
    pixels = two_cats()
    height, width = pixels.shape[:2]
    same = found.offered_detections(pixels, [], (width, height), "auto")
    double = found.offered_detections(pixels, [], (2 * width, 2 * height), "auto")
    assert len(same) == 2 and [d["class"] for d in double] == [d["class"] for d in same]
    for a, b in zip(same, double):
        assert max(abs(2 * p - q) for p, q in zip(a["box"], b["box"])) <= 0.2
    assert found.offered_detections(pixels, [], (width, height), "none") == []


def _box(mask: np.ndarray) -> tuple[int, int, int, int]:
    ys, xs = np.nonzero(mask)
    return int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1


def test_svg_silhouette_and_png_drawing(client):
    text = b'<svg xmlns="http://www.w3.org/2000/svg" width="512" height="256" viewBox="0 0 512 256">'
    text += b'<rect x="200" y="20" width="100" height="220" fill="#000"/></svg>'
    answer = upload(client, "shape.svg", text)
    assert answer.status_code == 200, answer.text
    data = answer.json()
    assert data["kind"] == "silhouette" and (data["width"], data["height"]) == (512, 256)
    x0, y0, w, h = data["objects"][0]["box"]
    assert abs(x0 - 200) <= 2 and abs(w - 100) <= 3
    # A drawing has nothing to click.
    refused = client.post(f"/api/photos/{data['photo']}/render", json={"objects": [{"positive": [[250, 100]]}]})
    assert refused.status_code == 422 and "nothing to click" in refused.json()["error"]
    assert client.get(f"/api/photos/{data['photo']}/hover").status_code == 404  # no hover preview either


def test_silhouette_png(client, tmp_path):
    path = write_silhouette_png(tmp_path / "person.png")
    answer = upload(client, "person.png", path.read_bytes())
    assert answer.status_code == 200 and answer.json()["kind"] == "silhouette"


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_bad_file_gets_the_command_lines_reason(client, name):
    data, words = BAD_FILES[name]
    answer = upload(client, name, data)
    assert answer.status_code == 422, answer.text
    reason = answer.json()["error"]
    assert reason.startswith(f"{name}: ") and words in reason
    assert "\n" not in reason and "Traceback" not in reason
    assert list(server_temp(client).iterdir()) == []


def test_decompression_bomb_against_the_pixel_cap(make_client):
    client = make_client(max_pixels=4000)
    answer = upload(client, "photo.png", png_bytes(scene().image))  # 400000 pixels
    assert answer.status_code == 422 and "over the --max-pixels limit" in answer.json()["error"]


def test_oversized_upload_is_413(make_client):
    client = make_client(max_upload=100_000)
    answer = upload(client, "big.png", b"\0" * 200_000)
    assert answer.status_code == 413 and "upload limit" in answer.json()["error"]
    # Without a Content-Length the streamed bytes are counted.
    head = b'--b\r\nContent-Disposition: form-data; name="file"; filename="big.png"\r\n\r\n'
    chunks = iter([head, b"x" * 60_000, b"x" * 60_000, b"\r\n--b--\r\n"])
    streamed = client.post("/api/photos", content=chunks, headers={"content-type": "multipart/form-data; boundary=b"})
    assert streamed.status_code == 413


def test_not_a_form_and_bad_json(client):
    assert client.post("/api/photos", content=b"hello").status_code == 400
    assert client.post("/api/photos", files={"other": ("a.png", b"x")}).status_code == 400
    first = upload(client, "two.png", png_bytes(scene().image)).json()
    bad = client.post(f"/api/photos/{first['photo']}/render", content=b"{nope")
    assert bad.status_code == 422 and "not valid JSON" in bad.json()["error"]
    for body, words in (
        ({"objects": [{"positive": [[1e5, 5]]}]}, "outside the 800x500 image"),
        ({"objects": [{"positive": [[1e300, 5]]}]}, "outside the 800x500 image"),
        ({"objects": [{"positive": [[int("9" * 401), 5]]}]}, "too large to be pixels"),
        ({"objects": [{"positive": [["a", 5]]}]}, "two numbers"),
        ({"objects": "x"}, "must be a list"),
        ({"options": {"style": "gold"}}, "unknown style"),
        ({"options": {"garment": "../../etc/passwd"}}, "unknown garment"),
    ):
        answer = client.post(f"/api/photos/{first['photo']}/render", json=body)
        assert answer.status_code == 422 and words in answer.json()["error"], (body, answer.text)


# ------------------------------------------------------------------ safety


@pytest.mark.parametrize("host", ["evil.example", "evil.example:8000", "127.0.0.1:9999", "localhost.evil.example", ""])
def test_foreign_host_is_refused(client, host):
    answer = client.get("/", headers={"host": host})
    assert answer.status_code == 400 and "Host" in answer.json()["error"]


@pytest.mark.parametrize("host", ["127.0.0.1:8000", "localhost:8000", "[::1]:8000", "localhost"])
def test_own_host_names_are_answered(client, host):
    assert client.get("/api/options", headers={"host": host}).status_code == 200


def test_foreign_origin_is_refused(client):
    for headers in ({"origin": "http://evil.example"}, {"origin": "null"}, {"sec-fetch-site": "cross-site"}):
        answer = client.post("/api/photos", headers=headers, files={"file": ("a.png", b"x")})
        assert answer.status_code == 403, headers
    same = client.post("/api/photos", headers={"origin": BASE}, files={"file": ("a.png", b"x")})
    assert same.status_code == 422  # let in, then refused as a bad file


def test_unknown_ids_and_kinds(client):
    assert client.get("/api/results/nope/image").status_code == 404
    assert client.get("/api/photos/nope/original").status_code == 404
    assert client.post("/api/photos/nope/render", json={}).status_code == 404
    first = upload(client, "two.png", png_bytes(scene().image)).json()
    assert client.get(f"/api/results/{first['result']}/passwd").status_code == 404
    assert client.get("/static/../cli/serve/app.py").status_code == 404
    assert client.get("/api/folder").status_code == 404  # not in folder mode
    assert client.get("/api/photos/nope/hover").status_code == 404


def test_the_hover_map_is_the_first_clicks_regions(client):
    """The page's hover preview map: superpixel labels of the working copy (480x300),
    the region a first click in each superpixel takes, and the regions; at the dog's
    middle, the dog."""
    import base64
    import zlib

    first = upload(client, "two.png", png_bytes(scene().image)).json()
    answer = client.get(f"/api/photos/{first['photo']}/hover")
    assert answer.status_code == 200 and answer.headers["content-type"] == "application/json"
    data = answer.json()
    assert (data["width"], data["height"], data["size"]) == (480, 300, [800, 500])

    def unpack(text: str, dtype: str) -> np.ndarray:
        return np.frombuffer(zlib.decompress(base64.b64decode(text)), dtype)

    labels = unpack(data["labels"], "<u2").reshape(300, 480)
    choice = unpack(data["choice"], "<i2")
    regions = np.unpackbits(unpack(data["regions"], "u1").reshape(-1, (data["count"] + 7) // 8), axis=1)
    assert labels.max() + 1 == data["count"] == len(choice)
    x, y = inside_point(scene().masks[1])
    region = regions[choice[labels[int(y * 0.6), int(x * 0.6)]]][: data["count"]].astype(bool)
    shown = region[labels]
    dog = cv2.resize(scene().masks[1].astype(np.uint8), (480, 300), interpolation=cv2.INTER_AREA) > 0
    assert (shown & dog).sum() / (shown | dog).sum() > 0.8


def test_full_pool_answers_503(make_client):
    client = make_client(workers=1, queue=0)
    state = client.app.app.state.jeanscv
    release = threading.Event()
    state.pool.submit_background(release.wait)
    try:
        answer = upload(client, "two.png", png_bytes(scene().image))
        assert answer.status_code == 503 and int(answer.headers["retry-after"]) >= 1
        assert "busy" in answer.json()["error"]
    finally:
        release.set()
    assert list(state.tmp.iterdir()) == []


def test_store_is_bounded_in_bytes():
    from jeanscv_cli.serve.store import Store

    store = Store(100)
    first = store.put("a", 60)
    second = store.put("b", 60)
    assert store.get(first) is None and store.get(second) == "b" and store.nbytes == 60
    third = store.put("c", 500)  # the newest stays, alone over the cap
    assert store.get(second) is None and store.get(third) == "c"
    assert len({first, second, third}) == 3 and len(first) >= 20


# ------------------------------------------------------------------ folder mode


@pytest.fixture
def folder(tmp_path):
    photos = tmp_path / "photos"
    photos.mkdir()
    Image.fromarray(scene().image).save(photos / "pets.png")
    write_silhouette_png(photos / "person.png")
    (photos / "notes.txt").write_text("not a photo")
    (tmp_path / "secret.png").write_bytes(png_bytes(scene().image))
    (photos / "link.png").symlink_to(tmp_path / "secret.png")  # points out of the folder: not served
    return photos


def test_folder_gallery_and_confinement(make_client, folder):
    client = make_client(folder=folder)
    listing = client.get("/api/folder").json()
    assert [item["name"] for item in listing["items"]] == ["person.png", "pets.png"]
    assert all(not item["output"] and item["uncertain"] is None for item in listing["items"])
    thumb = client.post(listing["items"][0]["thumb"])
    assert thumb.status_code == 200 and thumb.headers["content-type"] == "image/jpeg"
    assert (folder / "person.jeans.png").is_file()  # the command line's output, made on demand and kept
    # Once made here, whether its subject may be the wrong thing is known (a drawing's is sure).
    assert [item["uncertain"] for item in client.get("/api/folder").json()["items"]] == [False, None]
    for path in (
        "/api/folder/2/thumb",
        "/api/folder/-1/thumb",
        "/api/folder/..%2F..%2Fsecret.png/thumb",
        "/api/folder/../secret.png/thumb",
        "/api/folder/pets.png/thumb",
        "/api/folder/%2e%2e/thumb",
    ):
        assert client.post(path).status_code == 404, path
    assert client.post("/api/folder/..%2Fsecret.png/open").status_code == 404
    assert sorted(p.name for p in folder.parent.iterdir()) == ["photos", "secret.png"]


def test_folder_fix_with_clicks(make_client, folder):
    client = make_client(folder=folder)
    dog = scene().masks[1]
    items = client.get("/api/folder").json()["items"]
    index = next(item["item"] for item in items if item["name"] == "pets.png")
    opened = client.post(f"/api/folder/{index}/open")
    assert opened.status_code == 200, opened.text
    photo = opened.json()["photo"]
    point = inside_point(dog)
    saved = client.post(f"/api/folder/{index}/clicks", json={"photo": photo, "objects": [{"positive": [point]}]})
    assert saved.status_code == 200, saved.text
    assert saved.json()["clicks"] is True and saved.json()["output"] is True and saved.json()["uncertain"] is False
    assert read_clicks(sidecar_path(folder / "pets.png")) == Clicks.single([point], image_size=(800, 500))
    with Image.open(folder / "pets.jeans.png") as output:
        pixels = np.asarray(output.convert("RGB"))
    changed = np.any(pixels != scene().image, axis=-1)
    assert changed[dog].mean() > 0.1 and not changed[scene().masks[0]].any()
    # Opened again, the photo comes back with its saved clicks.
    again = client.post(f"/api/folder/{index}/open").json()
    assert again["clicks"] is True and again["saved_clicks"] == [{"positive": [list(point)], "negative": []}]
    # Another folder item's name cannot take these clicks.
    other = client.post("/api/folder/0/clicks", json={"photo": photo, "objects": [{"positive": [point]}]})
    assert other.status_code == 422
    # Back to automatic: only when said outright; the clicks file goes, the output is made again.
    clicked_output = (folder / "pets.jeans.png").read_bytes()
    assert client.post(f"/api/folder/{index}/clicks", json={"photo": photo, "objects": []}).status_code == 422
    reverted = client.post(f"/api/folder/{index}/clicks", json={"photo": photo, "objects": [], "revert": True})
    assert reverted.status_code == 200, reverted.text
    assert reverted.json()["clicks"] is False and not sidecar_path(folder / "pets.png").exists()
    assert (folder / "pets.jeans.png").read_bytes() != clicked_output
    assert client.post(f"/api/folder/{index}/open").json()["clicks"] is False


@pytest.mark.fresh_cuts  # counts the cuts
def test_a_folder_photo_is_cut_once_for_its_thumbnail_page_clicks_and_revert(
    make_client, folder, run_cli, monkeypatch, tmp_path
):
    """auto's hypotheses of a folder photo are cut once for its thumbnail's output, the
    page's result and click session, the clicks' output and the revert's (it was four
    cuts): the outputs are still the command line's, which cuts afresh."""
    from jeanscv.subject import photo as segmentation

    cuts = []
    hypotheses = segmentation.hypotheses
    monkeypatch.setattr(segmentation, "hypotheses", lambda *args: cuts.append(1) or hypotheses(*args))
    client = make_client(folder=folder)
    index = next(item["item"] for item in client.get("/api/folder").json()["items"] if item["name"] == "pets.png")
    assert client.post(f"/api/folder/{index}/thumb").status_code == 200
    automatic = (folder / "pets.jeans.png").read_bytes()
    photo = client.post(f"/api/folder/{index}/open").json()["photo"]
    assert client.get(f"/api/photos/{photo}/hover").status_code == 200  # the click session is made
    objects = [{"positive": [inside_point(scene().masks[1])], "negative": [inside_point(scene().masks[0])]}]
    assert client.post(f"/api/folder/{index}/clicks", json={"photo": photo, "objects": objects}).status_code == 200
    clicked = (folder / "pets.jeans.png").read_bytes()
    (tmp_path / "saved.clicks.json").write_bytes(sidecar_path(folder / "pets.png").read_bytes())
    reverted = client.post(f"/api/folder/{index}/clicks", json={"photo": photo, "objects": [], "revert": True})
    assert reverted.status_code == 200 and (folder / "pets.jeans.png").read_bytes() == automatic
    assert len(cuts) == 1
    result = run_cli(folder / "pets.png", "--clicks", tmp_path / "saved.clicks.json", "-o", tmp_path, "-q")
    assert result.exit_code == 0, result.stderr
    assert len(cuts) == 2  # the command line's own cut
    with Image.open(tmp_path / "pets.jeans.png") as cli_output, Image.open(io.BytesIO(clicked)) as served:
        assert np.array_equal(np.asarray(served), np.asarray(cli_output))


def test_folder_clicks_replay_through_the_command_line(make_client, folder, run_cli):
    """A clicks file saved by the page gives the same output through ``jeanscv FOLDER``,
    and the page's own full-size picture of those clicks is that output too."""
    client = make_client(folder=folder)
    items = client.get("/api/folder").json()["items"]
    index = next(item["item"] for item in items if item["name"] == "pets.png")
    photo = client.post(f"/api/folder/{index}/open").json()["photo"]
    objects = [{"positive": [inside_point(scene().masks[1])]}, {"positive": [inside_point(scene().masks[0])]}]
    page = client.post(f"/api/photos/{photo}/render", json={"objects": objects}).json()
    on_page = client.get(page["downloads"]["image"]).content
    assert client.post(f"/api/folder/{index}/clicks", json={"photo": photo, "objects": objects}).status_code == 200
    served = (folder / "pets.jeans.png").read_bytes()
    (folder / "pets.jeans.png").unlink()
    result = run_cli(folder, "-q", "-j", "1")  # the batch picks the saved clicks up (in this process)
    assert result.exit_code == 0, result.stderr
    with Image.open(folder / "pets.jeans.png") as cli_output:
        expected = np.asarray(cli_output)
    for picture in (served, on_page):
        with Image.open(io.BytesIO(picture)) as image:
            assert np.array_equal(np.asarray(image), expected)
    # The clicks dressed both objects, the dog first.
    changed = np.any(expected[..., :3] != scene().image, axis=-1)
    assert all(changed[mask].mean() > 0.1 for mask in scene().masks)
