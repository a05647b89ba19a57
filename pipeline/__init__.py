"""sem-pipeline: equiareal disk parameterizations of open triangle meshes by Stretch Energy
Minimization (Yueh, Lin, Wu, Yau, J. Sci. Comput. 78, 2019), and the stages built on them."""

__version__ = "0.1.0"
