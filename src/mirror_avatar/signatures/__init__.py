"""Motor signatures: IMS and their distances, people told apart, groups compared, likeness.

`signature` (the IMS of trials, EMD, the similarity space, strokes), `permutations` (permutation
tests of labelled units), `likeness` (can motion be told from a person's own trials),
`groups` (two groups of people compared), `identification` (each trial put with its nearest
person), `copying` (whether generated motion copies its training trials).
"""
