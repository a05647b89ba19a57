"""Open the pipeline's HTML pages in a real headless browser and check what a reader would see.

Selenium drives Debian's Chromium through Debian's chromedriver (``/usr/bin/chromium``,
``/usr/bin/chromedriver``; ``$CHROMIUM`` / ``$CHROMEDRIVER`` override them). Both paths are given
explicitly, so Selenium Manager is never asked to find or download anything.

    from browser import chrome, check_page          # chrome: module-scoped pytest fixture

    def test_report(chrome, tmp_path):
        counts = check_page(chrome, tmp_path / "report.html")
        assert counts["images"] == 4

``headless_chrome()`` is the same browser as a context manager. ``require_browser()`` skips the
test when the browser, its driver or selenium is missing, and fails it on CI (``CI=true``).

``check_page(driver, path, root=None)`` opens ``path`` as a file:// URL and asserts:

* the browser logged no SEVERE message (JavaScript errors, failed resource loads);
* every ``<img>`` loaded (``complete`` and ``naturalWidth > 0``) and is rendered with a
  non-zero width and height;
* every local ``<a href>`` (relative or file://) names an existing file or folder, and a
  ``#fragment`` names an existing ``id`` (or ``<a name>``) in the page it points to;
* no link, image or other resource (``script``, ``link``, ``source``, ``iframe``...) points
  outside ``root`` (default: the page's folder; pass the run folder for a stage's page) unless
  it is http(s) (links may also be ``mailto:``; ``data:`` URLs are inline).

It returns what it checked, so that tests can assert numbers: ``{"page", "root", "images",
"links", "local_links", "anchors", "external_links", "resources", "console", "image_paths",
"link_paths"}`` (counts; ``console``: the browser log entries below SEVERE; ``*_paths``: the
local files the images and links resolve to).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
from pathlib import Path
from urllib.parse import unquote, urldefrag, urlsplit

import pytest

CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver")
WINDOW = (1280, 1024)

# Everything the page asks the browser for, or lets the reader follow.
_COLLECT_JS = """
const out = {images: [], links: [], resources: []};
const rect = (e) => { const r = e.getBoundingClientRect(); return [r.width, r.height]; };
document.querySelectorAll('img').forEach((e, i) => out.images.push({
    index: i, src: e.currentSrc || e.src, raw: e.getAttribute('src'),
    complete: e.complete, naturalWidth: e.naturalWidth, size: rect(e)}));
document.querySelectorAll('a[href]').forEach((e) => out.links.push({
    href: e.href, raw: e.getAttribute('href'), text: (e.textContent || '').trim().slice(0, 60)}));
document.querySelectorAll(
    'script[src], link[href], source[src], source[srcset], iframe[src], video[src], '
    + 'audio[src], embed[src], object[data], img[srcset]').forEach((e) => {
    for (const attr of ['src', 'href', 'data']) {
        if (e.hasAttribute(attr) && !(e.tagName === 'IMG' && attr === 'src'))
            out.resources.push({tag: e.tagName.toLowerCase(), url: e[attr] || e.getAttribute(attr),
                                raw: e.getAttribute(attr)});
    }
    if (e.hasAttribute('srcset'))
        e.getAttribute('srcset').split(',').map((s) => s.trim().split(/\\s+/)[0]).filter(Boolean)
            .forEach((u) => out.resources.push({tag: e.tagName.toLowerCase(),
                                               url: new URL(u, document.baseURI).href, raw: u}));
});
return out;
"""

_IDS_JS = """
const ids = [];
document.querySelectorAll('[id]').forEach((e) => ids.push(e.id));
document.querySelectorAll('a[name]').forEach((e) => ids.push(e.getAttribute('name')));
return ids;
"""

# Lazily loaded images below the fold only load once scrolled to: bring each into view.
_SCROLL_IMAGES_JS = """
document.querySelectorAll('img').forEach((e) => { e.loading = 'eager'; e.scrollIntoView(); });
window.scrollTo(0, 0);
"""

_IMAGES_SETTLED_JS = """
return Array.from(document.querySelectorAll('img')).every((e) => e.complete);
"""


def browser_missing() -> str | None:
    """Why the headless browser cannot be started here, or None."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[test]')"
    for what, path in (("chromium", CHROMIUM), ("chromedriver", CHROMEDRIVER)):
        if not (Path(path).is_file() or shutil.which(path)):
            return f"{what} not found at {path} (Debian: apt-get install chromium chromium-driver)"
    return None


def require_browser() -> None:
    """Skip the calling test when there is no browser; fail it on CI (``CI=true``)."""
    reason = browser_missing()
    if reason is not None:
        if os.environ.get("CI") == "true":
            pytest.fail(reason)
        pytest.skip(reason)


@contextlib.contextmanager
def headless_chrome(width: int = WINDOW[0], height: int = WINDOW[1]):
    """One headless Chromium (Selenium WebDriver) for the block; quit on exit."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu",
                f"--window-size={width},{height}", "--hide-scrollbars",
                # file:// pages: no first-run, no extensions, no network probes
                "--no-first-run", "--disable-extensions", "--disable-background-networking"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        driver.set_page_load_timeout(60)
        driver.set_script_timeout(30)
        yield driver
    finally:
        driver.quit()


@pytest.fixture(scope="module")
def chrome():
    """One headless Chromium for the whole test module (import it: ``from browser import chrome``)."""
    require_browser()
    with headless_chrome() as driver:
        yield driver


def _file_path(url: str) -> Path:
    """Local path of a file:// URL (percent-decoded)."""
    return Path(unquote(urlsplit(url).path))


def _inside(path: Path, root: Path) -> bool:
    try:
        path.resolve().relative_to(root)
        return True
    except ValueError:
        return False


def _ids_in_file(path: Path) -> set[str]:
    """ids and <a name>s of another local HTML page (for links like other.html#x)."""
    text = path.read_text(errors="replace")
    return set(re.findall(r"""\b(?:id|name)\s*=\s*["']?([^"'\s>]+)""", text))


def check_page(driver, path, root=None, *, timeout: float = 20.0) -> dict:
    """Open ``path`` (a local HTML file) in ``driver`` and assert that it shows what it should.

    See the module docstring for what is checked. ``root``: the folder no local link or
    resource may leave (default: the page's folder). Returns the counts checked.
    """
    from selenium.webdriver.support.ui import WebDriverWait

    page = Path(path).resolve()
    root = Path(root).resolve() if root is not None else page.parent
    assert page.is_file(), f"{page}: no such page"
    assert _inside(page, root), f"{page}: the page is not inside its run folder {root}"
    name = str(page)

    driver.get_log("browser")  # drop what an earlier page left in the log
    driver.get(page.as_uri())
    driver.execute_script(_SCROLL_IMAGES_JS)
    try:
        WebDriverWait(driver, timeout).until(lambda d: d.execute_script(_IMAGES_SETTLED_JS))
    except Exception:  # the per-image check below names the ones still loading
        pass
    found = driver.execute_script(_COLLECT_JS)
    ids = set(driver.execute_script(_IDS_JS))
    log = driver.get_log("browser")

    problems: list[str] = []
    severe = [e for e in log if e.get("level") == "SEVERE"]
    for entry in severe:
        problems.append(f"console error: {entry.get('message')}")

    # Images: loaded, decoded, on screen, and from inside the run folder.
    for img in found["images"]:
        label = f"<img src={img['raw']!r}> (#{img['index']})"
        if not img["complete"] or not img["naturalWidth"]:
            problems.append(f"{label} did not load (complete={img['complete']}, "
                            f"naturalWidth={img['naturalWidth']})")
        width, height = img["size"]
        if not (width > 0 and height > 0):
            problems.append(f"{label} is not rendered: {width:g} x {height:g} px")
        problems.extend(_outside(label, img["src"], root))

    # Links: local ones resolve on disk (and their anchors in the target page).
    local = anchors = external = 0
    for link in found["links"]:
        label = f"<a href={link['raw']!r}> ({link['text']!r})"
        url, fragment = urldefrag(link["href"])
        scheme = urlsplit(url).scheme.lower()
        if scheme in ("http", "https", "mailto"):
            external += 1
            continue
        if scheme != "file":
            problems.append(f"{label} is neither a local file nor http(s): {link['href']}")
            continue
        target = _file_path(url)
        if target.resolve() == page:
            if fragment:
                anchors += 1
                if unquote(fragment) not in ids:
                    problems.append(f"{label}: no element with id {unquote(fragment)!r} on the page")
            continue
        local += 1
        outside = _outside(label, url, root)
        if outside:
            problems.extend(outside)
            continue
        if not target.exists():
            problems.append(f"{label} -> {target}: no such file or folder")
            continue
        if fragment and target.is_file() and target.suffix.lower() in (".html", ".htm"):
            anchors += 1
            if unquote(fragment) not in _ids_in_file(target):
                problems.append(f"{label}: no element with id {unquote(fragment)!r} in {target}")

    # Other resources (scripts, stylesheets, media): never from outside the run folder.
    for res in found["resources"]:
        problems.extend(_outside(f"<{res['tag']} {res['raw']!r}>", res["url"], root))

    assert not problems, f"{name}: {len(problems)} problem(s):\n  " + "\n  ".join(problems)
    return {"page": page, "root": root, "images": len(found["images"]),
            "image_paths": [_file_path(i["src"]) for i in found["images"]
                            if urlsplit(i["src"]).scheme == "file"],
            "link_paths": [_file_path(urldefrag(a["href"])[0]) for a in found["links"]
                           if urlsplit(a["href"]).scheme == "file"],
            "links": len(found["links"]), "local_links": local, "anchors": anchors,
            "external_links": external, "resources": len(found["resources"]),
            "console": len(log) - len(severe)}


def _outside(label: str, url: str, root: Path) -> list[str]:
    """A problem when ``url`` is neither http(s)/data nor a file inside ``root``."""
    scheme = urlsplit(url).scheme.lower()
    if scheme in ("http", "https", "data", "mailto", "about", "blob"):
        return []
    if scheme != "file":
        return [f"{label} points outside the run folder: {url}"]
    target = _file_path(urldefrag(url)[0])
    if not _inside(target, root):
        return [f"{label} points outside the run folder {root}: {target}"]
    return []


def screenshot(driver, path, png) -> Path:
    """Full-page screenshot of ``path`` into ``png`` (for looking at a page by eye)."""
    from selenium.webdriver.support.ui import WebDriverWait

    driver.get(Path(path).resolve().as_uri())
    driver.execute_script(_SCROLL_IMAGES_JS)
    WebDriverWait(driver, 20).until(lambda d: d.execute_script(_IMAGES_SETTLED_JS))
    # the window's own frame (outer - inner height) is not part of the screenshot
    height = driver.execute_script("return document.documentElement.scrollHeight"
                                   " + window.outerHeight - window.innerHeight")
    size = driver.get_window_size()
    driver.set_window_size(size["width"], max(size["height"], min(int(height) + 20, 16000)))
    try:
        driver.execute_script("window.scrollTo(0, 0)")
        driver.save_screenshot(str(png))
    finally:
        driver.set_window_size(size["width"], size["height"])
    return Path(png)
