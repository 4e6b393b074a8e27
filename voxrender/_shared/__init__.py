"""What several layers share, below all of them: threads (``threads``), memory-mapped reads (``mapped``), the
machine's memory (``memory``), text for messages (``text``), atomic files (``files``), the executors tasks run on
(``executors``) and the lazy faces of the packages (``face``).  Each module here imports nothing of voxrender's but
:mod:`voxrender.errors`.
"""
