"""snakemake --report on the shared ci-scale run: built without a warning, refused under a config the results
were not built with, and rendered in a headless Chromium (the report is a JavaScript app): each scene's
category, its plots, its metrics table and its own captions.

The browser loads the report file only: networking is switched off by flags (no name resolution, a dead
proxy), extensions, sync and component updates too, and Selenium is given Debian's chromedriver and
chromium, so it downloads nothing."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
SCENES = ("meteorite", "shear", "slide")          # the scenes of the shared ci run (conftest.py)
TARGETS = [f"results/{scene}/metrics.csv" for scene in SCENES]
EVALUATION = {"metrics over frames", "metrics table", "metrics.csv (download)", "rollout animation (GIF, a download)"}
# A phrase of each scene's dataset caption that no other scene's caption has.
DATASET_CAPTION = {"slide": "sliding-prone weak layer", "meteorite": "launched at the bed",
                   "shear": "direct shear box"}
CHROMIUM, CHROMEDRIVER = shutil.which("chromium"), shutil.which("chromedriver")
OFFLINE = ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1400,900",
           "--host-resolver-rules=MAP * ~NOTFOUND", "--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>",
           "--disable-background-networking", "--disable-component-update", "--disable-extensions",
           "--disable-sync", "--disable-default-apps", "--disable-domain-reliability", "--no-first-run",
           "--no-default-browser-check")

pytestmark = pytest.mark.engine


def snakemake_report(workdir: Path, out: Path, *config: str) -> subprocess.CompletedProcess:
    cmd = [SNAKEMAKE, "--report", str(out), "-s", str(ROOT / "workflow" / "Snakefile"), "-d", str(workdir),
           *(("--config", *config) if config else ()), "--", *TARGETS]
    return subprocess.run(cmd, capture_output=True, text=True)


@pytest.fixture(scope="module")
def report(ci_results, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("report") / "report.html"
    proc = snakemake_report(ci_results.parent, out, "scale=ci")
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log[-3000:]
    assert "warning" not in log.lower() and "Missing metadata" not in log, log[-3000:]
    assert out.stat().st_size > 100_000
    return out


def test_report_has_a_category_per_scene_and_no_warning(report):
    text = report.read_text()
    for scene in SCENES:
        assert f"results/{scene}/metrics.html" in text and f"results/{scene}/plots/dataset_sample.png" in text
    assert "Graph-DEM: learned surrogates of DEM simulations" in text       # the workflow description


@pytest.mark.parametrize("config, refusal", [
    ((), ("ScaleConflict", "holds results of scale=ci; this run asks for scale=default")),   # the 208 warnings
    (("scale=ci", "slide={n_sims: 5}"), ("ReportError", "were never built", "simulate")),   # a sim never run
])
def test_a_report_under_another_config_is_refused_without_warnings(ci_results, tmp_path, config, refusal):
    out = tmp_path / "report.html"
    proc = snakemake_report(ci_results.parent, out, *config)
    log = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert all(part in log for part in refusal), log[-3000:]
    assert "Missing metadata" not in log
    assert not out.exists()


@pytest.fixture(scope="module")
def browser():
    webdriver = pytest.importorskip("selenium.webdriver")
    if not (CHROMIUM and CHROMEDRIVER):
        pytest.skip("needs Debian's chromium and chromium-driver (make install)")
    from selenium.webdriver.chrome.service import Service
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in OFFLINE:
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    yield driver
    driver.quit()


def _wait(driver, condition, seconds: float = 20):
    from selenium.webdriver.support.ui import WebDriverWait
    return WebDriverWait(driver, seconds).until(condition)


def _menu_item(driver, text: str):
    """A navbar entry (category, subcategory) by its text, once the app has drawn it."""
    from selenium.webdriver.common.by import By
    return _wait(driver, lambda d: next((a for a in d.find_elements(By.CSS_SELECTOR, "li > a")
                                         if a.text.strip() == text), False))


def _open(driver, report: Path, scene: str, stage: str) -> dict:
    """Load the report, open the scene's category and the stage's subcategory: {label: its table row}."""
    from selenium.webdriver.common.by import By
    driver.get(report.as_uri())
    _menu_item(driver, scene).click()
    _menu_item(driver, stage).click()
    rows = _wait(driver, lambda d: d.find_elements(By.CSS_SELECTOR, "table tbody tr"))
    return {row.find_elements(By.TAG_NAME, "td")[0].text.strip(): row for row in rows}


def _view(driver, row):
    from selenium.webdriver.common.by import By
    row.find_element(By.CSS_SELECTOR, "a[iconname='eye']").click()


def _shown_image_width(driver, name: str) -> int:
    """naturalWidth of the image file ``name`` the report shows (an embedded data URI), once it has loaded."""
    from selenium.webdriver.common.by import By
    image = _wait(driver, lambda d: next((i for i in d.find_elements(By.CSS_SELECTOR, "img")
                                          if f"filename={name};" in (i.get_attribute("src") or "")), False))
    _wait(driver, lambda d: d.execute_script("return arguments[0].complete", image))
    return driver.execute_script("return arguments[0].naturalWidth", image)


@pytest.mark.parametrize("scene", SCENES)
def test_each_scene_renders_in_a_browser(report, browser, scene, tmp_path):
    from selenium.webdriver.common.by import By
    rows = _open(browser, report, scene, "evaluation")
    assert set(rows) == EVALUATION
    assert all(row.find_elements(By.TAG_NAME, "td")[1].text.strip() == scene for row in rows.values())
    _view(browser, rows["metrics over frames"])
    assert _shown_image_width(browser, "metrics_over_frames.png") > 500
    if scene == "slide":
        browser.save_screenshot(str(tmp_path / "report.png"))
        assert (tmp_path / "report.png").stat().st_size > 10_000

    # the metrics table: shown in a frame, every empty cell of the CSV named
    _view(browser, rows["metrics table"])
    frame = _wait(browser, lambda d: d.find_elements(By.TAG_NAME, "iframe"))[0]
    browser.switch_to.frame(frame)
    try:
        table = _wait(browser, lambda d: d.find_elements(By.TAG_NAME, "table"))[0].text
        assert "rollout MSE" in table and "n/a" in table and "nan" not in table.lower()
        if scene == "meteorite":            # at ci scale nothing is disturbed: the crater depth has no truth
            assert "undefined" in table and "zero or undefined in every scored frame" in table
    finally:
        browser.switch_to.default_content()

    # the GIF is a download in the report: its embedded data must still be an image the browser decodes
    width = browser.execute_async_script(
        "const done = arguments[1]; const image = new Image();"
        "image.onload = () => done(image.naturalWidth); image.onerror = () => done(-1);"
        "image.src = results[arguments[0]].data_uri;", f"results/{scene}/plots/rollout.gif")
    assert width > 100

    # the dataset sample, in the scene's other subcategory, with the caption of this scene
    rows = _open(browser, report, scene, "dataset")
    assert set(rows) == {"dataset sample (first and last frame)"}
    _view(browser, rows["dataset sample (first and last frame)"])
    assert _shown_image_width(browser, "dataset_sample.png") > 500
    captions = browser.execute_script(
        "return Object.fromEntries(Object.entries(results).map(([path, r]) => [path, r.caption]))")
    mine = captions[f"results/{scene}/plots/dataset_sample.png"]
    assert DATASET_CAPTION[scene] in mine
    assert not any(phrase in mine for other, phrase in DATASET_CAPTION.items() if other != scene)
    assert f"<strong>{scene}</strong>" in captions[f"results/{scene}/metrics.csv"]
