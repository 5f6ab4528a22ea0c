"""The page's wire decoder (static/decoder.js), run by node where it is installed, reads every
golden message as the Python decoder does."""
import json
import shutil
import subprocess

import pytest

from processes.network import wire
from processes.network.wire import protocol
from processes.network.web import STATIC
from tests.helpers.golden import GOLDEN
from tests.waits import DEADLINE_S


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed (apt-get install nodejs)")
def test_the_pages_decoder_reads_every_golden_message_as_python_does(tmp_path):
    script = tmp_path / "decode.mjs"
    script.write_text(f"""import {{ Decoder }} from {json.dumps((STATIC / 'decoder.js').as_uri())};
import {{ readFileSync }} from "fs";
const input = JSON.parse(readFileSync(0, "utf8"));
const decoder = new Decoder(input.protocol);
const out = {{}};
for (const [name, hex] of Object.entries(input.golden)) out[name] = decoder.decode(Uint8Array.from(Buffer.from(hex, "hex")));
console.log(JSON.stringify(out));
""")
    feed = json.dumps({"protocol": protocol.layout_json(), "golden": {k: v.hex() for k, v in GOLDEN.items()}})
    done = subprocess.run(["node", str(script)], input=feed, capture_output=True, text=True, timeout=DEADLINE_S)
    assert done.returncode == 0, done.stderr
    decoded = json.loads(done.stdout)
    for name, data in GOLDEN.items():
        message = wire.decode(data)
        js = decoded[name]
        assert (js["kind"], js["seq"], js["tick"], js["flags"]) == (message.kind.name.lower(), message.seq,
                                                                     message.tick, message.flags), name
        for field, value in message.fields.items():
            expected = value.hex() if isinstance(value, bytes) else (
                value.tolist() if hasattr(value, "tolist") else int(value) if isinstance(value, int) else value)
            assert js[field] == expected, (name, field)  # floats bit for bit: JSON round-trips float64
