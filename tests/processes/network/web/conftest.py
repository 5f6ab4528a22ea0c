"""The web tests' fixtures: a gateway with a bridge joined to it, and a headless browser."""
import shutil
import threading

import pytest

from processes.network.web.bridge import WebBridge
from tests.helpers.gateway import Rig
from tests.waits import DEADLINE_S, Deadline


@pytest.fixture
def bridged(zctx):
    """A gateway with a snapshot to serve, and a bridge joined to it as a spectator."""
    rig = Rig(zctx)
    bridge = WebBridge(rig.gateway.endpoint, "127.0.0.1:0")

    def pump_join():
        deadline = Deadline()
        while not deadline.expired():
            rig.step()
            if rig.gateway.counts["spectators_joined"]:
                return

    pumping = threading.Thread(target=pump_join, daemon=True)  # the gateway answers while start() waits
    pumping.start()
    url = bridge.start(DEADLINE_S)
    pumping.join(DEADLINE_S)
    yield rig, bridge, url
    bridge.stop()
    rig.close()


# --- in a real browser: headless Chromium through selenium --------------------------------------
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


CHROMEDRIVER = shutil.which("chromedriver")


INSTALL = "apt-get install chromium chromium-driver (as root) and pip install selenium; `make test` does both"


@pytest.fixture
def browser():
    """Headless Chromium with WebGL on SwiftShader (no GPU), its console kept; quit at the end."""
    webdriver = pytest.importorskip("selenium.webdriver", reason=f"selenium is not installed: {INSTALL}")
    if CHROMIUM is None or CHROMEDRIVER is None:
        pytest.skip(f"no chromium or chromedriver: {INSTALL}")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for flag in ("--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                 "--window-size=800,600", "--disable-dev-shm-usage"):
        options.add_argument(flag)
    options.binary_location = CHROMIUM
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_page_load_timeout(DEADLINE_S)
    driver.set_script_timeout(DEADLINE_S)
    yield driver
    driver.quit()
