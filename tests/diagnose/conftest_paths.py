from pathlib import Path

# ../shared beside the checkout: /work/main -> /work/shared; a worktree /work/wt/NAME too
SHARED = next((p / "shared" for p in Path(__file__).resolve().parents
               if (p / "shared" / "data").is_dir()), Path("/work/shared"))
