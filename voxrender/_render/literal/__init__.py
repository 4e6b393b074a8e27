"""The literal renderers: each algorithm as its paper writes it, kept beside the fast one as the tests' oracle.

Every renderer of :mod:`voxrender._render` is vectorised with NumPy; its literal version here follows the paper
step by step, one voxel, face or pixel at a time, in plain Python: slow on purpose, and never used to make a
picture.  The two must give the same coverage, the same depths within 1e-5 voxels and the same statistics.

The literal versions share no code with the production geometry (:mod:`voxrender._render.geometry`, the
:class:`~voxrender.space.view.View`'s mappings, :mod:`voxrender._render.clip`): :mod:`.geometry` writes the view
contract out again, so that a slip in either geometry shows as a disagreement.  Of the rest of voxrender they
take only the region octree (:mod:`voxrender.object.octree`), and no production module imports them
(``tests/test_render_literal.py`` checks both).

Which test holds which fast renderer to which literal one:

- ``ftb.render_ftb`` to :func:`.ftb.render_ftb_literal`, MERGE cases included: ``tests/test_render_ftb.py``;
- ``btf.render_btf`` to :func:`.btf.render_btf_literal`: ``tests/test_render_btf.py``;
- ``octree_btf.render_octree_btf`` to :func:`.octree_btf.render_octree_btf_literal`: ``tests/test_render_octree.py``;
- ``octree_ftb.render_octree_ftb`` to :func:`.octree_ftb.render_octree_ftb_literal`, blocked octants and the
  bitmaps' values included: ``tests/test_render_octree_ftb.py`` (and the literal one to the contract in
  ``tests/test_render_octree.py``);
- ``octree_sort.render_octree_sort`` (both orders), ``render_zbuffer`` and ``recode`` to
  :func:`.octree_sort.render_octree_sort_literal`, :func:`.octree_sort.render_zbuffer_literal` and
  :func:`.octree_sort.recode_literal`: ``tests/test_render_octree_sort.py``.

``tests/test_render_ftb.py`` also holds ftb, btf and octree-btf to theirs on a picture framed off the volume's
centre.  Ray casting and the gamma turn of a pre-image have no literal version: ``tests/reference.py``, an
independent ray marcher, checks them (``tests/test_render_raycast.py``, ``tests/test_contract.py``).
"""
