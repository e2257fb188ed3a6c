import sys

from .cli import main

if __name__ == "__main__":          # not when a spawned worker process imports it
    from .allocator import keep_freed_memory
    keep_freed_memory()
    sys.exit(main())
