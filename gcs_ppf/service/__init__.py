"""The asyncio shell: missions and runs, the tick, fleet, links, launch, store and settings."""
