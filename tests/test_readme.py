"""The README's Python examples run as written."""

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_examples_run():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
    assert len(blocks) >= 2
    namespace: dict = {}
    for block in blocks:  # later blocks build on the names of earlier ones
        exec(compile(block, f"{README.name} example", "exec"), namespace)
    assert namespace["result"].success and namespace["trajectory"].duration > 0
    assert namespace["poses"].shape[0] == 10_000
